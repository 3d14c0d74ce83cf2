"""The exact centroid tables (SingleInputCentroids, LabelPairCentroids) against the dense evaluation.

The tables are piecewise in the input (or the clip level): exact between breakpoints, wrong inside an
interval if a breakpoint is missing. The breakpoints are derived here independently (Gaussian
inverses and the crossing of two Gaussians from their ratio of sigmas, not the engine's quadratic), and
the tables are compared with a dense min/max/centroid evaluation on each breakpoint, beside it and at
the midpoint of every interval between them. Deterministic and fast: this file carries most of the
engine's mutation kills (`make mutation`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pytest
from numpy.testing import assert_allclose
from smm_controller.fuzzy import (
    ZERO_AREA_FALLBACK,
    FuzzyVariable,
    GaussianMF,
    MamdaniSystem,
    TriangularMF,
    centroid_weights,
    uniform_grid,
)
from smm_controller.fuzzy_batch import MamdaniBatch, evaluate_system
from smm_controller.fuzzy_tables import LabelPairCentroids, SingleInputCentroids
from smm_controller.rules import (
    fleso_bandwidth_system,
    fleso_input_variable,
    fleso_output_variable,
    pd_output_variable,
)

FloatArray = npt.NDArray[np.float64]
ATOL = 1e-13
# Building and evaluating the tables must not divide by zero or take the log of 0 on the way.
pytestmark = pytest.mark.filterwarnings("error")


def dense_centroids(grid: FloatArray, aggregated: FloatArray) -> FloatArray:
    """Centroid of the piecewise-linear interpolation of each row, by the segment integrals."""
    x0, x1 = grid[:-1], grid[1:]
    m0, m1 = aggregated[..., :-1], aggregated[..., 1:]
    width = x1 - x0
    area = np.sum(width * (m0 + m1) / 2.0, axis=-1)
    moment = np.sum(width * (x0 * (m0 + m1) / 2.0 + width * (m0 / 6.0 + m1 / 3.0)), axis=-1)
    safe = np.where(area > 0.0, area, 1.0)
    return np.where(area > 0.0, moment / safe, ZERO_AREA_FALLBACK)


def with_neighbours_and_midpoints(points: Sequence[float], low: float, high: float) -> FloatArray:
    """Each point, its two float neighbours and the midpoint of every interval between the points."""
    inside = np.unique([p for p in points if low < p < high])
    edges = np.concatenate(([low], inside, [high]))
    midpoints = 0.5 * (edges[:-1] + edges[1:])
    neighbours = [math.nextafter(p, d) for p in inside for d in (-math.inf, math.inf)]
    return np.concatenate((edges, midpoints, neighbours))


# --- one Gaussian input ---------------------------------------------------------------------------------


def gaussian_crossings(sigma_mean: Sequence[tuple[float, float]], values: FloatArray) -> list[float]:
    """Inputs where a label's membership equals a sampled value or another label's membership."""
    points = []
    for mean, sigma in sigma_mean:
        # exp(-d^2 / (2 sigma^2)) = v  <=>  d = sigma sqrt(2 ln(1/v))
        distance = sigma * np.sqrt(2.0 * np.log(1.0 / values[(values > 0.0) & (values <= 1.0)]))
        points += [*(mean - distance), *(mean + distance)]
    for i, (mean_a, sigma_a) in enumerate(sigma_mean):
        for mean_b, sigma_b in sigma_mean[i + 1 :]:
            # |x - mean_a| / sigma_a = |x - mean_b| / sigma_b, so x - mean_a = +-r (x - mean_b)
            ratio = sigma_a / sigma_b
            for sign in (1.0, -1.0):
                if 1.0 - sign * ratio != 0.0:
                    points.append((mean_a - sign * ratio * mean_b) / (1.0 - sign * ratio))
    return points


def single_input_reference(
    sigma_mean: Sequence[tuple[float, float]],
    consequents: Sequence[Sequence[int]],
    samples: FloatArray,
    grid: FloatArray,
    x: FloatArray,
) -> FloatArray:
    """Dense Mamdani: per output, max over the rules of min(mu_a(x), output MF), then the centroid."""
    n_outputs = samples.shape[0]
    result = np.empty((x.size, n_outputs))
    for o in range(n_outputs):
        aggregated = np.zeros((x.size, grid.size))
        for a, (mean, sigma) in enumerate(sigma_mean):
            label = consequents[a][o]
            if label < 0:
                continue
            membership = np.exp(-((x - mean) ** 2) / (2.0 * sigma**2))
            aggregated = np.maximum(aggregated, np.minimum(membership[:, None], samples[o, label][None, :]))
        result[:, o] = dense_centroids(grid, aggregated)
    return result


def triangle_samples(grid: FloatArray, peaks: Sequence[float], half_width: float) -> FloatArray:
    return np.array([np.clip(1.0 - np.abs(grid - p) / half_width, 0.0, None) for p in peaks])


def gaussian_samples(grid: FloatArray, means: Sequence[float], sigma: float) -> FloatArray:
    return np.array([np.exp(-((grid - m) ** 2) / (2.0 * sigma**2)) for m in means])


def fleso_case(
    grid_points: int,
) -> tuple[list[tuple[float, float]], list[tuple[int, ...]], FloatArray, FloatArray]:
    grid = np.linspace(-1.0, 1.0, grid_points)
    inputs = [(mf.mean, mf.sigma) for mf in fleso_input_variable().mfs]  # type: ignore[attr-defined]
    outputs = np.array([mf.sample(grid) for mf in fleso_output_variable().mfs])
    return inputs, [(0,), (1,), (2,), (1,), (0,)], outputs[None], grid


def uneven_case() -> tuple[list[tuple[float, float]], list[tuple[int, ...]], FloatArray, FloatArray]:
    """Unequal sigmas (Gaussians cross twice), two outputs with their own label counts, missing rules."""
    grid = np.linspace(-2.0, 1.5, 61)
    # (0.4, 0.5) and (0.3, 0.08) conclude the same labels and cross twice, at 0.281 and 0.314.
    inputs = [(-1.0, 0.3), (-0.2, 0.15), (0.4, 0.5), (0.4, 0.2), (1.1, 0.35), (0.3, 0.08)]
    gaussian_family = gaussian_samples(grid, [-1.5, -0.2, 0.9, 1.4], 0.3)
    triangle_family = np.vstack((triangle_samples(grid, [-1.0, 0.0, 1.0], 0.6), np.zeros((1, grid.size))))
    samples = np.stack((gaussian_family, 0.8 * triangle_family))
    # Output 0: labels 3, 0, 3, 1, 2, 3. Output 1: no rule for the second input label, three conclude
    # label 2, none label 0 (so where only label 0 is positive no rule clips anything).
    consequents = [(3, 1), (0, -1), (3, 2), (1, 2), (2, 1), (3, 2)]
    return inputs, consequents, samples, grid


def mean_on_a_peak_case() -> tuple[list[tuple[float, float]], list[tuple[int, ...]], FloatArray, FloatArray]:
    """On a coarse grid no crossing lies near the mean 0 of the middle label (sigma 0.2), so the nearest
    ones are symmetric about it; its rule concludes B, whose peak 1.0 is a grid point: x = 0, where
    that membership equals the sample 1.0, is a breakpoint of its own."""
    grid = np.linspace(-1.0, 1.0, 5)
    outputs = np.array([mf.sample(grid) for mf in fleso_output_variable().mfs])
    return [(-1.0, 0.3), (0.0, 0.2), (1.0, 0.45)], [(0,), (2,), (1,)], outputs[None], grid


CASES = {
    "mean-on-a-peak": mean_on_a_peak_case,
    "fleso-201": lambda: fleso_case(201),
    "fleso-51": lambda: fleso_case(51),
    "fleso-3": lambda: fleso_case(3),
    "uneven": uneven_case,
}


@pytest.mark.parametrize("case", list(CASES))
def test_single_input_table_equals_the_dense_evaluation_everywhere(case: str) -> None:
    """On, beside and between every breakpoint of the input: the worst places for a missing one."""
    inputs, consequents, samples, grid = CASES[case]()
    table = SingleInputCentroids(
        [(mean, 2.0 * sigma**2) for mean, sigma in inputs], consequents, samples, centroid_weights(grid)
    )
    low, high = min(m for m, _ in inputs), max(m for m, _ in inputs)
    assert (table.low, table.high) == (low, high)
    x = with_neighbours_and_midpoints(gaussian_crossings(inputs, np.unique(samples)), low, high)
    values = np.array([table.evaluate(float(v)) for v in x])
    assert_allclose(
        values, single_input_reference(inputs, consequents, samples, grid, x), rtol=0.0, atol=ATOL
    )


def test_an_output_no_rule_concludes_falls_back_to_zero() -> None:
    inputs, consequents, samples, grid = uneven_case()
    silent = [(label, -1) for label, _ in consequents]
    table = SingleInputCentroids(
        [(mean, 2.0 * sigma**2) for mean, sigma in inputs], silent, samples, centroid_weights(grid)
    )
    x = np.array([-1.0, -0.3, 0.5, 1.1])
    expected = single_input_reference(inputs, silent, samples, grid, x)
    assert_allclose(expected[:, 1], ZERO_AREA_FALLBACK, atol=0.0)
    assert_allclose([table.evaluate(float(v)) for v in x], expected, rtol=0.0, atol=ATOL)


def test_single_input_table_is_none_outside_the_means() -> None:
    inputs, consequents, samples, grid = uneven_case()
    table = SingleInputCentroids(
        [(mean, 2.0 * sigma**2) for mean, sigma in inputs], consequents, samples, centroid_weights(grid)
    )
    for x in (math.nextafter(-1.0, -2.0), math.nextafter(1.1, 2.0), math.nan, -math.inf):
        assert table.evaluate(x) is None
    assert table.evaluate(-1.0) is not None
    assert table.evaluate(1.1) is not None


def test_identical_input_labels_need_no_crossing() -> None:
    """Two labels with the same MF (a legal rule base) never cross: no breakpoint, no division by 0.

    Equal sigmas elsewhere: -1 and 0.2 cross once, at -0.4 (not mirrored by another pair).
    """
    grid = np.linspace(-1.0, 1.0, 21)
    inputs = [(-1.0, 0.4), (0.2, 0.4), (0.2, 0.4), (1.0, 0.4)]
    consequents = [(0,), (1,), (2,), (0,)]
    samples = gaussian_samples(grid, [-1.0, 0.0, 1.0], 0.5)[None]
    table = SingleInputCentroids(
        [(mean, 2.0 * sigma**2) for mean, sigma in inputs], consequents, samples, centroid_weights(grid)
    )
    assert all(math.isfinite(b) for b in table.breakpoints)
    x = with_neighbours_and_midpoints(gaussian_crossings(inputs, np.unique(samples)), -1.0, 1.0)
    values = np.array([table.evaluate(float(v)) for v in x])
    assert_allclose(
        values, single_input_reference(inputs, consequents, samples, grid, x), rtol=0.0, atol=ATOL
    )


def test_single_input_batch_of_a_system_with_two_outputs() -> None:
    """MamdaniBatch builds the table from a MamdaniSystem (labels, rules, output order) as the dense path."""
    inputs, consequents, samples, grid = uneven_case()
    names = ("A", "B", "C", "D", "E", "F")
    variable = FuzzyVariable(names, [GaussianMF(m, s) for m, s in inputs])
    first = FuzzyVariable(("P", "Q", "R", "S"), [GaussianMF(m, 0.3) for m in (-1.5, -0.2, 0.9, 1.4)])
    second = FuzzyVariable(("U", "V", "W"), [TriangularMF(p - 0.6, p, p + 0.6) for p in (-1.0, 0.0, 1.0)])
    rules = {
        (names[a],): (first.labels[c[0]], second.labels[c[1]]) for a, c in enumerate(consequents) if c[1] >= 0
    }
    system = MamdaniSystem((variable,), (first, second), rules, grid_points=grid.size, universe=(-2.0, 1.5))
    batch = MamdaniBatch([system, system])
    assert batch._single_input_plan is not None
    second_samples = np.vstack((triangle_samples(grid, [-1.0, 0.0, 1.0], 0.6), np.zeros((1, grid.size))))
    reference_samples = np.stack((samples[0], second_samples))
    # B has no rule (its second output is -1 above), so it fires nothing in either output.
    reference_rules = [c if c[1] >= 0 else (-1, -1) for c in consequents]
    x = with_neighbours_and_midpoints(gaussian_crossings(inputs, np.unique(reference_samples)), -1.0, 1.1)
    expected = single_input_reference(inputs, reference_rules, reference_samples, grid, x)
    for k in range(0, x.size, 7):
        value = batch.evaluate([(float(x[k]),), (float(x[-1 - k]),)])
        assert_allclose(value, [expected[k], expected[-1 - k]], rtol=0.0, atol=ATOL)


# --- one or two clipped output labels -------------------------------------------------------------------


FAMILIES = {
    # Wide labels overlap above 1/2 (the paper's cross at 1/2): both clipped, the larger level wins.
    "wide-gaussians-21": lambda: (
        np.linspace(-1.0, 1.0, 21),
        FuzzyVariable(("L", "M", "H"), [GaussianMF(m, 0.5) for m in (-0.5, 0.0, 0.6)]),
    ),
    "pd-gaussians-51": lambda: (np.linspace(-1.0, 1.0, 51), pd_output_variable()),
    "fleso-gaussians-201": lambda: (np.linspace(-1.0, 1.0, 201), fleso_output_variable()),
    "triangles-7": lambda: (
        np.linspace(-1.0, 1.0, 7),
        FuzzyVariable(("N", "Z", "P"), [TriangularMF(c - 0.7, c, c + 0.7) for c in (-0.8, 0.1, 0.9)]),
    ),
}


def family_samples(family: str) -> tuple[FloatArray, FloatArray]:
    grid, variable = FAMILIES[family]()
    return grid, np.array([mf.sample(grid) for mf in variable.mfs])


@pytest.mark.parametrize("family", list(FAMILIES))
def test_one_clipped_label_equals_the_dense_centroid(family: str) -> None:
    grid, samples = family_samples(family)
    tables = LabelPairCentroids(samples, centroid_weights(grid))
    for label, row in enumerate(samples):
        levels = with_neighbours_and_midpoints(list(row), 0.0, 1.0)[1:]  # level 0 fires nothing
        expected = dense_centroids(grid, np.minimum(levels[:, None], row[None, :]))
        assert_allclose([tables.single(label, s) for s in levels], expected, rtol=0.0, atol=ATOL)


@pytest.mark.parametrize("family", list(FAMILIES))
def test_two_clipped_labels_equal_the_dense_centroid(family: str) -> None:
    """Levels s and 1 - s, in both argument orders, on and between the levels where a comparison flips."""
    grid, samples = family_samples(family)
    tables = LabelPairCentroids(samples, centroid_weights(grid))
    for a in range(len(samples)):
        for b in range(a + 1, len(samples)):
            first, second = samples[a], samples[b]
            flips = [*first, *second, *(1.0 - first), *(1.0 - second), 0.5]
            levels = with_neighbours_and_midpoints(flips, 0.0, 1.0)
            levels = levels[(levels > 0.0) & (levels < 1.0)]
            aggregated = np.maximum(
                np.minimum(levels[:, None], first[None, :]),
                np.minimum(1.0 - levels[:, None], second[None, :]),
            )
            expected = dense_centroids(grid, aggregated)
            forward = [tables.pair(a, s, b, 1.0 - s) for s in levels]
            backward = [tables.pair(b, 1.0 - s, a, s) for s in levels]
            assert_allclose(forward, expected, rtol=0.0, atol=ATOL)
            assert_allclose(backward, expected, rtol=0.0, atol=ATOL)


def test_pair_of_a_label_with_itself_is_not_a_pair() -> None:
    grid, samples = family_samples("triangles-7")
    with pytest.raises(KeyError):
        LabelPairCentroids(samples, centroid_weights(grid)).pair(1, 0.5, 1, 0.5)


# --- MamdaniSystem set-up ------------------------------------------------------------------------------


def test_outputs_with_different_label_counts_match_brute_force() -> None:
    """Output label rows are padded to the largest family; every label sampled in its own row."""
    grid = np.linspace(-1.0, 1.0, 41)
    small = FuzzyVariable(("L", "H"), [TriangularMF(-2.0, -1.0, 1.0), TriangularMF(-1.0, 1.0, 2.0)])
    large = FuzzyVariable(("a", "b", "c", "d"), [GaussianMF(m, 0.3) for m in (-0.9, -0.3, 0.3, 0.9)])
    variable = FuzzyVariable(("N", "P"), [TriangularMF(-3.0, -1.0, 1.0), TriangularMF(-1.0, 1.0, 3.0)])
    rules = {("N",): ("H", "b"), ("P",): ("L", "d")}
    system = MamdaniSystem((variable,), (small, large), rules, grid_points=41)
    assert system.n_labels == 4
    assert_allclose(system.output_samples[:2, 0], [mf.sample(grid) for mf in small.mfs], atol=0)
    assert not system.output_samples[2:, 0].any()
    assert_allclose(system.output_samples[:, 1], [mf.sample(grid) for mf in large.mfs], atol=0)
    for x in (-0.6, 0.0, 0.35, 1.0):
        mu_n, mu_p = (1.0 - x) / 2.0, (1.0 + x) / 2.0  # hand-computed memberships of N and P
        expected = [
            dense_centroids(
                grid,
                np.maximum(
                    np.minimum(mu_n, small.mfs[1].sample(grid)), np.minimum(mu_p, small.mfs[0].sample(grid))
                ),
            ),
            dense_centroids(
                grid,
                np.maximum(
                    np.minimum(mu_n, large.mfs[1].sample(grid)), np.minimum(mu_p, large.mfs[3].sample(grid))
                ),
            ),
        ]
        assert_allclose(evaluate_system(system, (x,)), expected, rtol=0.0, atol=ATOL)
        assert_allclose(
            system.label_strengths((x,)), [mu_p, mu_n, 0.0, 0.0, 0.0, mu_n, 0.0, mu_p], atol=1e-15
        )


def test_flat_index_orders_the_antecedents_as_the_inputs() -> None:
    """Three inputs of 2, 3 and 2 labels: each rule fires exactly where its own labels are active."""
    two = FuzzyVariable(("n", "p"), [TriangularMF(-3.0, -1.0, 1.0), TriangularMF(-1.0, 1.0, 3.0)])
    three = FuzzyVariable(
        ("l", "m", "h"),
        [TriangularMF(-2.0, -1.0, 0.0), TriangularMF(-1.0, 0.0, 1.0), TriangularMF(0.0, 1.0, 2.0)],
    )
    output = FuzzyVariable(tuple("ABCDEFGHIJKL"), [GaussianMF(-1.0 + 2.0 * k / 11, 0.05) for k in range(12)])
    rules = {}
    for i, a in enumerate(two.labels):
        for j, b in enumerate(three.labels):
            for k, c in enumerate(two.labels):
                rules[(a, b, c)] = (output.labels[(i * 3 + j) * 2 + k],)
    system = MamdaniSystem((two, three, two), (output,), rules, grid_points=101)
    # x = (1, -1, -1): only (p, l, n) fires, with strength 1.
    strengths = system.label_strengths((1.0, -1.0, -1.0))
    assert strengths == [1.0 if k == (1 * 3 + 0) * 2 + 0 else 0.0 for k in range(12)]
    # x = (-1, 0.5, 1): (n, m, p) at 0.5 and (n, h, p) at 0.5.
    strengths = system.label_strengths((-1.0, 0.5, 1.0))
    assert strengths == [0.5 if k in (1 * 2 + 1, 2 * 2 + 1) else 0.0 for k in range(12)]


def test_rule_errors_name_the_rule_and_the_label() -> None:
    variable = FuzzyVariable(("N", "P"), [GaussianMF(-1.0, 0.5), GaussianMF(1.0, 0.5)])
    with pytest.raises(
        ValueError, match=r"rule \('N', 'P'\) -> \('N',\) does not match 1 inputs and 1 outputs"
    ):
        MamdaniSystem((variable,), (variable,), {("N", "P"): ("N",)})
    with pytest.raises(
        ValueError, match=r"rule \('N',\) -> \('N', 'P'\) does not match 1 inputs and 1 outputs"
    ):
        MamdaniSystem((variable,), (variable,), {("N",): ("N", "P")})
    with pytest.raises(ValueError, match=r"unknown label 'Z'; labels are \('N', 'P'\)"):
        MamdaniSystem((variable,), (variable,), {("N",): ("Z",)})
    with pytest.raises(ValueError, match="at least one input and one output"):
        MamdaniSystem((variable,), (), {})


def test_label_strengths_of_two_different_inputs_by_hand() -> None:
    """Two inputs with their own labels (2 and 3): each input's degrees come from its own variable."""
    two = FuzzyVariable(("n", "p"), [TriangularMF(-3.0, -1.0, 1.0), TriangularMF(-1.0, 1.0, 3.0)])
    three = FuzzyVariable(
        ("l", "m", "h"),
        [TriangularMF(-2.0, -1.0, 0.0), TriangularMF(-1.0, 0.0, 1.0), TriangularMF(0.0, 1.0, 2.0)],
    )
    output = FuzzyVariable(tuple("ABCDEF"), [GaussianMF(-1.0 + 0.4 * k, 0.1) for k in range(6)])
    rules = {
        (a, b): (output.labels[i * 3 + j],)
        for i, a in enumerate(two.labels)
        for j, b in enumerate(three.labels)
    }
    system = MamdaniSystem((two, three), (output,), rules, grid_points=51)
    # x = (0.5, -0.25): n = 0.25, p = 0.75; l = 0.25, m = 0.75, h = 0.
    assert system.label_strengths((0.5, -0.25)) == pytest.approx(
        [0.25, 0.25, 0.0, 0.25, 0.75, 0.0], abs=1e-15
    )
    # x = (-0.5, 0.5): n = 0.75, p = 0.25; l = 0, m = 0.5, h = 0.5.
    assert system.label_strengths((-0.5, 0.5)) == pytest.approx([0.0, 0.5, 0.5, 0.0, 0.25, 0.25], abs=1e-15)


@pytest.mark.parametrize("x", [-1.5, -1.0, -0.3, 0.0, 0.6, 1.0, 1.2])
def test_label_strengths_of_one_gaussian_input_by_hand(x: float) -> None:
    """FLESO labels, rules NB, PS -> S; NS, PB -> M; ZE -> B (not mirror-symmetric, unlike the paper's),
    with mu(x) = exp(-(x - c)^2 / (2 sigma^2))."""
    sigma = 0.25 / math.sqrt(2.0 * math.log(2.0))
    mu = {c: math.exp(-((x - c) ** 2) / (2.0 * sigma**2)) for c in (-1.0, -0.5, 0.0, 0.5, 1.0)}
    rules = {("NB",): ("S",), ("NS",): ("M",), ("ZE",): ("B",), ("PS",): ("S",), ("PB",): ("M",)}
    system = MamdaniSystem((fleso_input_variable(),), (fleso_output_variable(),), rules, grid_points=21)
    expected = [max(mu[-1.0], mu[0.5]), max(mu[-0.5], mu[1.0]), mu[0.0]]
    assert system.label_strengths((x,)) == pytest.approx(expected, rel=1e-14, abs=1e-300)


def test_a_label_with_no_sample_above_zero_has_no_centroid() -> None:
    """A triangle narrower than the grid spacing samples to zeros: area 0, the fallback value."""
    grid = np.linspace(-1.0, 1.0, 5)
    samples = np.array([TriangularMF(0.1, 0.2, 0.3).sample(grid), TriangularMF(-1.0, 0.0, 1.0).sample(grid)])
    assert not samples[0].any()
    tables = LabelPairCentroids(samples, centroid_weights(grid))
    assert tables.single(0, 0.7) == ZERO_AREA_FALLBACK
    assert tables.single(1, 0.5) == pytest.approx(0.0, abs=1e-15)  # symmetric about 0


def test_two_labels_with_no_sample_above_zero_have_no_centroid() -> None:
    grid = np.linspace(-1.0, 1.0, 5)
    samples = np.array([TriangularMF(0.1, 0.2, 0.3).sample(grid), TriangularMF(0.6, 0.7, 0.8).sample(grid)])
    assert LabelPairCentroids(samples, centroid_weights(grid)).pair(0, 0.25, 1, 0.75) == ZERO_AREA_FALLBACK


@pytest.mark.parametrize("x", [(0.3, -0.2), (1.0, 0.0), (1.0, 1.0), (-1.0, 0.4)])
def test_lattice_system_whose_output_samples_to_zero_falls_back(x: tuple[float, float]) -> None:
    """One, two or four rules fire, but the output MFs lie between grid points: area 0 everywhere."""
    partition = FuzzyVariable(("N", "P"), [TriangularMF(-3.0, -1.0, 1.0), TriangularMF(-1.0, 1.0, 3.0)])
    narrow = FuzzyVariable(("A", "B"), [TriangularMF(0.1, 0.2, 0.3), TriangularMF(0.6, 0.7, 0.8)])
    rules = {("N", "N"): ("A",), ("N", "P"): ("B",), ("P", "N"): ("B",), ("P", "P"): ("A",)}
    system = MamdaniSystem((partition, partition), (narrow,), rules, grid_points=5)
    batch = MamdaniBatch([system])
    assert batch._lattice_plan is not None
    assert not system.aggregated_membership(x).any()
    assert batch.evaluate_flat([x]) == [ZERO_AREA_FALLBACK]


# --- set-up errors name what is wrong; set-up details -------------------------------------------------


def exact(message: str) -> str:
    return f"^{re.escape(message)}$"


def test_membership_function_errors_name_the_parameter() -> None:
    with pytest.raises(ValueError, match=exact("mean must be a finite number, got nan")):
        GaussianMF(math.nan, 1.0)
    with pytest.raises(ValueError, match=exact("sigma must be a finite number, got inf")):
        GaussianMF(0.0, math.inf)
    with pytest.raises(ValueError, match=exact("mean must be a finite number, got True")):
        GaussianMF(True, 1.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=exact("sigma must be a finite number, got '1'")):
        GaussianMF(0.0, "1")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=exact("b must be a finite number, got nan")):
        TriangularMF(0.0, math.nan, 1.0)


def test_grid_and_variable_errors() -> None:
    assert_allclose(centroid_weights([0.0, 1.0]), [[0.5, 1.0 / 6.0], [0.5, 1.0 / 3.0]], rtol=1e-15)
    grid_message = "grid must be a strictly increasing 1-D array of at least 2 points"
    with pytest.raises(ValueError, match=exact(grid_message)):
        centroid_weights([0.0])
    with pytest.raises(ValueError, match=exact("universe must satisfy low < high, got (1.0, 1.0)")):
        uniform_grid((1.0, 1.0), 5)
    with pytest.raises(ValueError, match="must be non-empty and of equal length, got 0 labels and 0 mfs"):
        FuzzyVariable((), ())


def test_peaks_evenly_spaced_with_a_foot_off_are_no_partition() -> None:
    """Only the first triangle's left foot is off: not a uniform partition, every label is evaluated."""
    variable = FuzzyVariable(
        ("A", "B", "C"),
        [TriangularMF(-1.0, 0.0, 0.5), TriangularMF(0.0, 0.5, 1.0), TriangularMF(0.5, 1.0, 1.5)],
    )
    assert variable.lattice_pair(0.2) is None
    assert variable.active(0.2) == [(0, pytest.approx(0.6)), (1, pytest.approx(0.4))]


def test_batch_and_system_errors_name_what_is_wrong() -> None:
    system = fleso_bandwidth_system(21)
    with pytest.raises(ValueError, match=exact("MamdaniBatch needs at least one system")):
        MamdaniBatch([])
    narrower = MamdaniSystem(
        (fleso_input_variable(),),
        (FuzzyVariable(("S", "M", "B"), [GaussianMF(m, 0.3) for m in (-1.0, 0.0, 1.0)]),),
        {("ZE",): ("B",)},
        grid_points=21,
    )
    with pytest.raises(
        ValueError, match=exact("all systems of a MamdaniBatch must share output MFs and grid")
    ):
        MamdaniBatch([system, narrower])
    with pytest.raises(
        ValueError, match=exact("a MamdaniSystem needs at least one input and one output variable")
    ):
        MamdaniSystem((), (fleso_output_variable(),), {})
    with pytest.raises(ValueError, match=exact("expected 1 inputs, got 2")):
        MamdaniBatch([system]).evaluate_flat([(0.1, 0.2)])


def test_system_keeps_its_universe_and_read_only_samples() -> None:
    system = MamdaniSystem(
        (fleso_input_variable(),), (fleso_output_variable(),), {("ZE",): ("B",)}, universe=(-2.0, 3.0)
    )
    assert system.universe == (-2.0, 3.0)
    assert (system.grid[0], system.grid[-1]) == (-2.0, 3.0)
    with pytest.raises(ValueError, match="read-only"):
        system.output_samples[0, 0, 0] = 0.5


@pytest.mark.parametrize("x", [(0.3, -0.2), (-0.6, 0.5), (1.0, 0.0), (0.5, -1.0), (-1.0, 1.0)])
def test_two_input_systems_with_different_inputs_match_brute_force(x: tuple[float, float]) -> None:
    """Lattice inputs of 2 and 3 labels (the fast path), and a Gaussian first input (the general path)."""
    two = FuzzyVariable(("n", "p"), [TriangularMF(-3.0, -1.0, 1.0), TriangularMF(-1.0, 1.0, 3.0)])
    three = FuzzyVariable(
        ("l", "m", "h"),
        [TriangularMF(-2.0, -1.0, 0.0), TriangularMF(-1.0, 0.0, 1.0), TriangularMF(0.0, 1.0, 2.0)],
    )
    gaussian = FuzzyVariable(("n", "p"), [GaussianMF(-1.0, 0.6), GaussianMF(1.0, 0.6)])
    output = FuzzyVariable(tuple("ABCDEF"), [GaussianMF(-1.0 + 0.4 * k, 0.2) for k in range(6)])
    for first in (two, gaussian):
        rules = {
            (a, b): (output.labels[(i * 3 + j * 5) % 6],)
            for i, a in enumerate(first.labels)
            for j, b in enumerate(three.labels)
        }
        system = MamdaniSystem((first, three), (output,), rules, grid_points=41)
        grid = system.grid
        aggregated = np.zeros_like(grid)
        for (a, b), (c,) in rules.items():
            level = min(first.mfs[first.index(a)].degree(x[0]), three.mfs[three.index(b)].degree(x[1]))
            aggregated = np.maximum(aggregated, np.minimum(level, output.mfs[output.index(c)].sample(grid)))
        expected = float(dense_centroids(grid, aggregated))
        assert MamdaniBatch([system]).evaluate_flat([x]) == pytest.approx([expected], abs=ATOL)
