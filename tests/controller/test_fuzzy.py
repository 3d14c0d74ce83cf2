"""Fuzzy inference engine: membership functions, centroid, Mamdani min/min/max against brute force."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_controller.fuzzy import (
    ZERO_AREA_FALLBACK,
    FuzzyVariable,
    GaussianMF,
    MamdaniSystem,
    TriangularMF,
    centroid,
    centroid_weights,
    gaussian_mf,
    triangular_mf,
    uniform_grid,
)
from smm_controller.fuzzy_batch import MamdaniBatch, evaluate_system
from smm_controller.rules import (
    TABLE_1,
    fleso_bandwidth_system,
    fleso_input_variable,
    fleso_output_variable,
    pd_gain_system,
    pd_input_variable,
    pd_output_variable,
)

unit = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False, allow_subnormal=True)


Rules = Mapping[tuple[str, ...], tuple[str, ...]]


def brute_force_outputs(system: MamdaniSystem, rules: Rules, x: tuple[float, ...]) -> list[float]:
    """Mamdani min/min/max + trapezoid centroid, written independently: every rule, every label."""
    grid = system.grid
    results = []
    for o, output in enumerate(system.outputs):
        aggregated = np.zeros_like(grid)
        for antecedent in itertools.product(*(range(len(v.labels)) for v in system.inputs)):
            firing = min(
                v.mfs[i].degree(value) for v, i, value in zip(system.inputs, antecedent, x, strict=True)
            )
            labels = tuple(v.labels[i] for v, i in zip(system.inputs, antecedent, strict=True))
            consequent = rules.get(labels)
            if consequent is None:
                continue
            mf = output.mfs[output.index(consequent[o])]
            aggregated = np.maximum(aggregated, np.minimum(firing, mf.sample(grid)))
        area = np.trapezoid(aggregated, grid)
        moment_area = sum(
            # exact integral of x * (linear interpolation) on each segment
            (x1 - x0) * (x0 * (m0 + m1) / 2 + (x1 - x0) * (m0 / 6 + m1 / 3))
            for x0, x1, m0, m1 in zip(grid[:-1], grid[1:], aggregated[:-1], aggregated[1:], strict=True)
        )
        results.append(moment_area / area if area > 0 else ZERO_AREA_FALLBACK)
    return results


PD_RULES: Rules = {
    (e, ce): TABLE_1[r][c]
    for r, ce in enumerate(("NB", "NM", "NS", "ZE", "PS", "PM", "PB"))
    for c, e in enumerate(("NB", "NM", "NS", "ZE", "PS", "PM", "PB"))
}


@pytest.fixture(scope="module")
def pd_system() -> MamdaniSystem:
    """Built in the test session, not at import: mutation testing imports the tests before any mutant."""
    return MamdaniSystem(
        (pd_input_variable(), pd_input_variable()), (pd_output_variable(), pd_output_variable()), PD_RULES
    )


class TestMembershipFunctions:
    def test_triangle_values(self) -> None:
        assert_allclose(triangular_mf([-1.0, 0.0, 0.5, 1.0, 2.0, 3.0], 0.0, 1.0, 3.0), [0, 0, 0.5, 1, 0.5, 0])

    def test_gaussian_values(self) -> None:
        assert_allclose(gaussian_mf([0.0, 2.0], 0.0, 2.0), [1.0, math.exp(-0.5)])

    @settings(max_examples=200, deadline=None)
    @given(x=st.floats(-3, 3, allow_subnormal=True))
    def test_scalar_and_array_forms_agree(self, x: float) -> None:
        tri = TriangularMF(-0.5, 0.25, 1.0)
        gauss = GaussianMF(0.3, 0.4)
        assert tri.degree(x) == pytest.approx(float(tri.sample(x)), abs=1e-15)
        assert gauss.degree(x) == pytest.approx(float(gauss.sample(x)), rel=1e-14)

    @pytest.mark.parametrize(("a", "b", "c"), [(0, 0, 1), (0, 1, 1), (1, 0, 2), (0, math.nan, 1)])
    def test_triangle_rejects_degenerate(self, a: float, b: float, c: float) -> None:
        with pytest.raises(ValueError, match=r"a < b < c|finite"):
            TriangularMF(a, b, c)

    @pytest.mark.parametrize("sigma", [0.0, -1.0, math.inf])
    def test_gaussian_rejects_bad_sigma(self, sigma: float) -> None:
        with pytest.raises(ValueError, match="sigma"):
            GaussianMF(0.0, sigma)


class TestSpecMembershipShapes:
    def test_adjacent_input_triangles_cross_at_half(self) -> None:
        variable = pd_input_variable()
        centres = [mf.b for mf in variable.mfs]  # type: ignore[attr-defined]
        assert_allclose(centres, np.linspace(-1, 1, 7), atol=1e-15)
        for left, right in zip(variable.mfs[:-1], variable.mfs[1:], strict=True):
            midpoint = 0.5 * (left.b + right.b)  # type: ignore[attr-defined]
            assert left.degree(midpoint) == pytest.approx(0.5)
            assert right.degree(midpoint) == pytest.approx(0.5)

    @settings(max_examples=200, deadline=None)
    @given(x=unit)
    def test_input_triangles_sum_to_one(self, x: float) -> None:
        assert sum(pd_input_variable().memberships(x)) == pytest.approx(1.0, abs=1e-12)

    @pytest.mark.parametrize("family", [pd_output_variable, fleso_input_variable, fleso_output_variable])
    def test_gaussians_cross_at_half_midway(self, family: Callable[[], FuzzyVariable]) -> None:
        variable = family()  # built in the test, not at collection (mutation testing)
        for left, right in zip(variable.mfs[:-1], variable.mfs[1:], strict=True):
            midpoint = 0.5 * (left.mean + right.mean)  # type: ignore[attr-defined]
            assert left.degree(midpoint) == pytest.approx(0.5, abs=1e-12)
            assert right.degree(midpoint) == pytest.approx(0.5, abs=1e-12)
            assert left.degree(left.mean) == 1.0  # type: ignore[attr-defined]

    def test_spec_centres(self) -> None:
        assert [mf.mean for mf in fleso_input_variable().mfs] == [-1, -0.5, 0, 0.5, 1]  # type: ignore[attr-defined]
        assert [mf.mean for mf in fleso_output_variable().mfs] == [-1, 0, 1]  # type: ignore[attr-defined]


class TestActiveLabels:
    @settings(max_examples=200, deadline=None)
    @given(x=st.floats(-1.5, 1.5, allow_subnormal=True))
    def test_lattice_shortcut_equals_all_labels(self, x: float) -> None:
        variable = pd_input_variable()
        dense = np.zeros(7)
        for i, degree in variable.active(x):
            dense[i] = degree
        assert_allclose(dense, variable.memberships(x), rtol=0, atol=1e-12)
        assert len(variable.active(x)) <= 2

    @settings(max_examples=200, deadline=None)
    @given(x=st.floats(-1.5, 1.5, allow_subnormal=True))
    def test_gaussian_shortcut_is_bit_identical(self, x: float) -> None:
        variable = fleso_input_variable()
        assert variable.active(x) == list(enumerate(variable.memberships(x)))

    def test_non_uniform_triangles_use_every_label(self) -> None:
        variable = FuzzyVariable(("A", "B"), (TriangularMF(-1, 0, 2), TriangularMF(-2, 1, 3)))
        assert [i for i, _ in variable.active(0.5)] == [0, 1]

    def test_unknown_label_is_rejected(self) -> None:
        with pytest.raises(ValueError, match="unknown label"):
            pd_input_variable().index("XX")

    def test_variable_shape_checks(self) -> None:
        with pytest.raises(ValueError, match="equal length"):
            FuzzyVariable(("A",), ())
        with pytest.raises(ValueError, match="unique"):
            FuzzyVariable(("A", "A"), (GaussianMF(0, 1), GaussianMF(1, 1)))


class TestCentroid:
    def test_weights_integrate_piecewise_linear_exactly(self) -> None:
        grid = np.linspace(-1.0, 1.0, 11)
        membership = 1.0 - np.abs(grid - 0.2)  # piecewise linear with a kink at a grid point
        area, moment = membership @ centroid_weights(grid)
        fine = np.linspace(-1.0, 1.0, 200001)
        fine_membership = np.interp(fine, grid, membership)
        assert area == pytest.approx(np.trapezoid(fine_membership, fine), rel=1e-9)
        assert moment == pytest.approx(np.trapezoid(fine * fine_membership, fine), rel=1e-8)

    @settings(max_examples=50, deadline=None)
    @given(st.lists(st.floats(0.0, 1.0, allow_subnormal=True), min_size=5, max_size=40))
    def test_matches_scikit_fuzzy_defuzz(self, samples: list[float]) -> None:
        skfuzzy = pytest.importorskip("skfuzzy")
        membership = np.array(samples)
        # skfuzzy divides by max(area, machine eps), so it deviates for areas below eps.
        assume(membership.max() > 1e-6)
        grid = np.linspace(-1.0, 1.0, membership.size)
        assert centroid(grid, membership) == pytest.approx(
            skfuzzy.defuzz(grid, membership, "centroid"), abs=1e-12
        )

    def test_zero_area_falls_back_to_zero(self) -> None:
        assert centroid(np.linspace(0.0, 1.0, 5), np.zeros(5)) == ZERO_AREA_FALLBACK == 0.0

    @pytest.mark.parametrize("grid", [[0.0], [0.0, 0.0, 1.0], [[0.0, 1.0]]])
    def test_weights_reject_bad_grids(self, grid: list[float]) -> None:
        with pytest.raises(ValueError, match="strictly increasing"):
            centroid_weights(grid)

    def test_uniform_grid_rejects_too_few_points(self) -> None:
        with pytest.raises(ValueError, match="grid_points"):
            uniform_grid((-1.0, 1.0), 2)
        with pytest.raises(ValueError, match="low < high"):
            uniform_grid((1.0, -1.0), 5)


class TestMamdani:
    @settings(max_examples=60, deadline=None)
    @given(e=unit, ce=unit)
    def test_pd_system_matches_brute_force(self, pd_system: MamdaniSystem, e: float, ce: float) -> None:
        assert_allclose(
            evaluate_system(pd_system, (e, ce)), brute_force_outputs(pd_system, PD_RULES, (e, ce)), atol=1e-12
        )

    @settings(max_examples=30, deadline=None)
    @given(s=unit)
    def test_fleso_system_matches_brute_force(self, s: float) -> None:
        rules: Rules = {("NB",): ("S",), ("NS",): ("M",), ("ZE",): ("B",), ("PS",): ("M",), ("PB",): ("S",)}
        system = MamdaniSystem((fleso_input_variable(),), (fleso_output_variable(),), rules)
        assert_allclose(evaluate_system(system, (s,)), brute_force_outputs(system, rules, (s,)), atol=1e-12)
        assert_allclose(
            evaluate_system(fleso_bandwidth_system(), (s,)), evaluate_system(system, (s,)), atol=0
        )

    @settings(max_examples=30, deadline=None)
    @given(x=st.tuples(unit, unit, unit))
    def test_three_input_generic_path_matches_brute_force(self, x: tuple[float, float, float]) -> None:
        labels = ("N", "Z", "P")
        variable = FuzzyVariable(labels, [GaussianMF(c, 0.4) for c in (-1.0, 0.0, 1.0)])
        rules: Rules = {
            combo: (labels[(sum(labels.index(label) for label in combo)) % 3],)
            for combo in itertools.product(labels, repeat=3)
        }
        system = MamdaniSystem((variable, variable, variable), (variable,), rules, grid_points=51)
        assert_allclose(evaluate_system(system, x), brute_force_outputs(system, rules, x), atol=1e-12)

    def test_aggregated_membership_is_max_of_clipped_labels(self, pd_system: MamdaniSystem) -> None:
        strengths = pd_system.label_strengths((0.51, 0.2))
        aggregated = pd_system.aggregated_membership((0.51, 0.2))
        n = pd_system.n_labels
        for o, output in enumerate(pd_system.outputs):
            expected = np.max(
                [
                    np.minimum(strengths[o * n + i], mf.sample(pd_system.grid))
                    for i, mf in enumerate(output.mfs)
                ],
                axis=0,
            )
            assert_allclose(aggregated[o], expected, atol=0)
            assert evaluate_system(pd_system, (0.51, 0.2))[o] == pytest.approx(
                centroid(pd_system.grid, expected), abs=1e-14
            )

    def test_no_rule_fires_gives_fallback(self) -> None:
        variable = pd_input_variable()
        system = MamdaniSystem((variable,), (pd_output_variable(),), {("PB",): ("PB",)})
        assert evaluate_system(system, (-1.0,)) == (ZERO_AREA_FALLBACK,)
        assert evaluate_system(system, (1.0,))[0] > 0.5

    def test_batch_equals_individual_systems(self, pd_system: MamdaniSystem) -> None:
        other = pd_gain_system(tuple(reversed(TABLE_1)))
        batch = MamdaniBatch([pd_system, other])
        inputs = [(0.3, -0.7), (-0.9, 0.15)]
        result = batch.evaluate(inputs)
        assert_allclose(result[0], evaluate_system(pd_system, inputs[0]), atol=1e-15)
        assert_allclose(result[1], evaluate_system(other, inputs[1]), atol=1e-15)

    def test_batch_rejects_mismatched_outputs_and_inputs(self, pd_system: MamdaniSystem) -> None:
        with pytest.raises(ValueError, match="share output"):
            MamdaniBatch([pd_system, fleso_bandwidth_system()])
        with pytest.raises(ValueError, match="at least one"):
            MamdaniBatch([])
        with pytest.raises(ValueError, match="expected 1 input vectors"):
            MamdaniBatch([pd_system]).evaluate([(0.0, 0.0), (0.0, 0.0)])
        with pytest.raises(ValueError, match="expected 2 inputs"):
            pd_system.label_strengths((0.0,))

    def test_rule_arity_and_labels_are_checked(self) -> None:
        variable = pd_input_variable()
        with pytest.raises(ValueError, match="does not match"):
            MamdaniSystem((variable,), (pd_output_variable(),), {("PB", "PB"): ("PB",)})
        with pytest.raises(ValueError, match="unknown label"):
            MamdaniSystem((variable,), (pd_output_variable(),), {("XX",): ("PB",)})
        with pytest.raises(ValueError, match="at least one input"):
            MamdaniSystem((), (pd_output_variable(),), {})
