"""MamdaniBatch's fast paths equal the dense Mamdani min/min/max evaluation (SPEC section 4).

The clip-and-max in numpy (four rules per system) is bit for bit the dense evaluation; the tabulated
centroids (one or two rules, single-input rule bases) agree with it up to rounding: 1e-13 on outputs
in [-1, 1].
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_controller.fuzzy import (
    ZERO_AREA_FALLBACK,
    FuzzyVariable,
    MamdaniSystem,
    TriangularMF,
    centroid,
    centroid_weights,
    uniform_grid,
)
from smm_controller.fuzzy_batch import MamdaniBatch
from smm_controller.fuzzy_pd import FuzzyPDGainSchedule
from smm_controller.fuzzy_tables import LabelPairCentroids, SingleInputCentroids
from smm_controller.rules import (
    PD_LABELS,
    TABLE_1,
    TABLE_7,
    fleso_bandwidth_system,
    fleso_input_variable,
    fleso_output_variable,
    pd_gain_system,
    pd_input_variable,
    pd_output_variable,
)

ATOL = 1e-13

PEAKS = [-1.0 + 2.0 * i / 6 for i in range(7)]
# Peaks, the ends and their float neighbours: where one label has degree 0 or rounding picks the interval.
SPECIAL = sorted(
    {x for peak in PEAKS for x in (peak, math.nextafter(peak, -2.0), math.nextafter(peak, 2.0))} | {0.0, -0.0}
)
values = st.one_of(st.floats(-1.2, 1.2, allow_nan=False, allow_subnormal=True), st.sampled_from(SPECIAL))


def _dense_reference(systems: Sequence[MamdaniSystem], inputs: Sequence[Sequence[float]]) -> list[float]:
    """min/min/max over every label and the centroid as one matrix product, as before the fast path."""
    aggregated = np.concatenate(
        [system.aggregated_membership(x) for system, x in zip(systems, inputs, strict=True)]
    )
    weights = centroid_weights(systems[0].grid)
    return [
        moment / area if area > 0.0 else ZERO_AREA_FALLBACK
        for area, moment in np.dot(np.ascontiguousarray(aggregated), weights).tolist()
    ]


@pytest.fixture(scope="module", params=[201, 51, 7])
def pd_systems(request: pytest.FixtureRequest) -> tuple[MamdaniSystem, MamdaniSystem]:
    return pd_gain_system(TABLE_1, request.param), pd_gain_system(TABLE_7, request.param)


@settings(max_examples=100, deadline=None)
@given(x=st.tuples(values, values, values, values))
def test_pd_batch_equals_the_dense_evaluation(
    pd_systems: tuple[MamdaniSystem, MamdaniSystem], x: tuple[float, float, float, float]
) -> None:
    inputs = ((x[0], x[1]), (x[2], x[3]))
    reference = _dense_reference(pd_systems, inputs)
    assert_allclose(MamdaniBatch(pd_systems).evaluate_flat(inputs), reference, rtol=0.0, atol=ATOL)


@settings(max_examples=100, deadline=None)
@given(
    x=st.tuples(
        *[
            st.floats(-0.99, 0.99, allow_nan=False, allow_subnormal=True).filter(
                lambda v: min(abs(v - p) for p in PEAKS) > 1e-6
            )
        ]
        * 4
    )
)
def test_four_rules_per_joint_are_bit_for_bit_the_dense_evaluation(
    pd_systems: tuple[MamdaniSystem, MamdaniSystem], x: tuple[float, float, float, float]
) -> None:
    """No input on a peak: four rules fire per joint, clipped and aggregated in numpy."""
    inputs = ((x[0], x[1]), (x[2], x[3]))
    assert MamdaniBatch(pd_systems).evaluate_flat(inputs) == _dense_reference(pd_systems, inputs)


@pytest.mark.parametrize(
    ("e", "ce"),
    [
        (0.0, 0.0),  # both on a peak: one rule fires
        (1.0, -1.0),  # both clipped to the ends: one rule fires
        (1.0 / 3.0, 0.1),  # one on a peak: two rules
        (0.1, -2.0 / 3.0),  # two rules, the other input on a peak
        (0.51, 0.2),  # the worked example of Section III.B: four rules
        (0.2, -0.4),  # four rules
    ],
)
def test_pd_batch_with_one_two_or_four_rules_per_joint(
    pd_systems: tuple[MamdaniSystem, MamdaniSystem], e: float, ce: float
) -> None:
    batch = MamdaniBatch(pd_systems)
    for inputs in (((e, ce), (0.51, 0.2)), ((0.0, 0.0), (e, ce)), ((e, ce), (e, ce))):
        assert_allclose(
            batch.evaluate_flat(inputs), _dense_reference(pd_systems, inputs), rtol=0.0, atol=ATOL
        )


def test_pd_batch_matches_the_documented_centroid() -> None:
    """Against centroid() of each system's aggregate, an independent evaluation of eq. 17."""
    systems = (pd_gain_system(TABLE_1), pd_gain_system(TABLE_7))
    batch = MamdaniBatch(systems)
    rng = np.random.default_rng(7)
    for x in rng.uniform(-1.0, 1.0, (200, 4)):
        inputs = ((x[0], x[1]), (x[2], x[3]))
        expected = [
            centroid(system.grid, membership)
            for system, point in zip(systems, inputs, strict=True)
            for membership in system.aggregated_membership(point)
        ]
        assert_allclose(batch.evaluate_flat(inputs), expected, rtol=0.0, atol=1e-14)


@pytest.fixture(scope="module", params=[201, 51, 3])
def fleso_systems(request: pytest.FixtureRequest) -> tuple[MamdaniSystem, MamdaniSystem]:
    system = fleso_bandwidth_system(request.param)
    return system, system


@settings(max_examples=100, deadline=None)
@given(
    s=st.tuples(
        st.floats(-1.5, 1.5, allow_nan=False, allow_subnormal=True),
        st.floats(-1.5, 1.5, allow_nan=False, allow_subnormal=True),
    )
)
def test_single_input_batch_equals_the_dense_evaluation(
    fleso_systems: tuple[MamdaniSystem, MamdaniSystem], s: tuple[float, float]
) -> None:
    inputs = ((s[0],), (s[1],))
    reference = _dense_reference(fleso_systems, inputs)
    assert_allclose(MamdaniBatch(fleso_systems).evaluate_flat(inputs), reference, rtol=0.0, atol=ATOL)


def test_single_input_table_on_and_beside_every_breakpoint(
    fleso_systems: tuple[MamdaniSystem, MamdaniSystem],
) -> None:
    """Where a membership crosses a sampled value the pattern of clipping changes: the worst places."""
    system = fleso_systems[0]
    table = SingleInputCentroids(
        [(mf.mean, 2.0 * mf.sigma**2) for mf in fleso_input_variable().mfs],
        [(0,), (1,), (2,), (1,), (0,)],  # NB->S, NS->M, ZE->B, PS->M, PB->S
        np.transpose(system.output_samples, (1, 0, 2)),
        centroid_weights(system.grid),
    )
    points = [p for b in table.breakpoints for p in (b, math.nextafter(b, -2.0), math.nextafter(b, 2.0))]
    for x in [-1.0, 1.0, *points]:
        (value,) = table.evaluate(x) or [math.nan]
        assert value == pytest.approx(centroid(system.grid, system.aggregated_membership((x,))[0]), abs=ATOL)
    assert table.evaluate(1.0 + 1e-12) is None
    assert table.evaluate(math.nan) is None


@pytest.mark.parametrize(
    ("gaussians", "consequents", "samples", "weights", "message"),
    [
        (  # weights for another grid
            [(0.0, 1.0)],
            [(0,)],
            np.ones((1, 1, 5)),
            np.ones((4, 2)),
            "samples must have shape (outputs, labels, n) and weights shape (n, 2), got (1, 1, 5) and (4, 2)",
        ),
        (  # samples not per output
            [(0.0, 1.0)],
            [(0,)],
            np.ones((1, 5)),
            np.ones((5, 2)),
            "samples must have shape (outputs, labels, n) and weights shape (n, 2), got (1, 5) and (5, 2)",
        ),
        (  # a rule missing
            [(0.0, 1.0), (1.0, 1.0)],
            [(0,)],
            np.ones((1, 1, 5)),
            np.ones((5, 2)),
            "consequents must give one output label per input label (2) and output (1), "
            "got rows of lengths [1]",
        ),
        (  # a rule for one output of two
            [(0.0, 1.0)],
            [(0,)],
            np.ones((2, 1, 5)),
            np.ones((5, 2)),
            "consequents must give one output label per input label (1) and output (2), "
            "got rows of lengths [1]",
        ),
    ],
)
def test_single_input_table_rejects_inconsistent_shapes(
    gaussians: list[tuple[float, float]],
    consequents: list[tuple[int, ...]],
    samples: np.ndarray,
    weights: np.ndarray,
    message: str,
) -> None:
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        SingleInputCentroids(gaussians, consequents, samples, weights)


@pytest.mark.parametrize("family", [pd_output_variable, fleso_output_variable])
def test_label_pair_centroids_match_the_dense_centroid(family: object) -> None:
    variable = family()  # type: ignore[operator]
    grid = uniform_grid((-1.0, 1.0), 201)
    samples = np.array([mf.sample(grid) for mf in variable.mfs])
    tables = LabelPairCentroids(samples, centroid_weights(grid))
    rng = np.random.default_rng(3)
    for level in [*rng.uniform(0.0, 1.0, 40), 1.0, 0.5, *samples[1][::10]]:
        for label in range(len(samples)):
            expected = centroid(grid, np.minimum(level, samples[label]))
            assert tables.single(label, level) == pytest.approx(expected, abs=ATOL)
        for first in range(len(samples)):
            for second in range(len(samples)):
                if first == second:
                    continue
                other = 1.0 - level
                aggregate = np.maximum(np.minimum(level, samples[first]), np.minimum(other, samples[second]))
                value = tables.pair(first, level, second, other)
                assert value == pytest.approx(centroid(grid, aggregate), abs=ATOL)


def test_label_pair_centroids_reject_inconsistent_shapes() -> None:
    message = "samples must have shape (labels, n) and weights shape (n, 2), got (2, 5) and (4, 2)"
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        LabelPairCentroids(np.ones((2, 5)), np.ones((4, 2)))


def test_incomplete_rule_base_uses_the_general_path() -> None:
    """A cell without a rule does not fire; outside the rules nothing fires and the fallback is used."""
    variable = pd_input_variable()
    rules: dict[tuple[str, ...], tuple[str, ...]] = {("ZE", "ZE"): ("PB",), ("PS", "ZE"): ("NB",)}
    system = MamdaniSystem((variable, variable), (pd_output_variable(),), rules)
    batch = MamdaniBatch([system])
    for inputs in (((0.1, 0.0),), ((0.2, 0.1),), ((-0.5, 0.9),)):
        assert_allclose(batch.evaluate_flat(inputs), _dense_reference([system], inputs), rtol=0.0, atol=ATOL)
    assert batch.evaluate_flat(((-0.9, -0.9),)) == [ZERO_AREA_FALLBACK]


@settings(max_examples=200, deadline=None)
@given(x=st.floats(-1.0, 1.0, allow_nan=False, allow_subnormal=True))
def test_lattice_pair_gives_the_two_triangle_memberships(x: float) -> None:
    check_lattice_pair(x)


@pytest.mark.parametrize("x", [x for x in SPECIAL if -1.0 <= x <= 1.0])
def test_lattice_pair_on_and_beside_the_peaks(x: float) -> None:
    """Where rounding puts x in the neighbouring interval and a side exceeds 1 before its clamp."""
    check_lattice_pair(x)


def check_lattice_pair(x: float) -> None:
    variable = pd_input_variable()
    pair = variable.lattice_pair(x)
    assert pair is not None
    k, degree_k, degree_next = pair
    assert 0 <= k < len(PD_LABELS) - 1
    memberships = variable.memberships(x)
    assert_allclose([degree_k, degree_next], memberships[k : k + 2], rtol=0.0, atol=1e-15)
    others = [m for i, m in enumerate(memberships) if i not in (k, k + 1)]
    assert max(others, default=0.0) <= 1e-15
    assert 0.0 <= degree_k <= 1.0 and 0.0 <= degree_next <= 1.0
    assert [(i, d) for i, d in ((k, degree_k), (k + 1, degree_next)) if d > 0.0] == variable.active(x)


@pytest.mark.parametrize("x", [-1.0 - 1e-9, 1.5, math.nan, math.inf])
def test_lattice_pair_is_none_off_the_lattice(x: float) -> None:
    assert pd_input_variable().lattice_pair(x) is None


def test_lattice_pair_is_none_without_a_uniform_triangular_partition() -> None:
    assert fleso_input_variable().lattice_pair(0.0) is None
    uneven = FuzzyVariable(
        ("A", "B", "C"), [TriangularMF(-1, 0, 0.5), TriangularMF(0, 0.5, 1), TriangularMF(0.5, 1, 2)]
    )
    assert uneven.lattice_pair(0.2) is None


@settings(max_examples=100, deadline=None)
@given(e=st.tuples(values, values), e_dot=st.tuples(values, values))
def test_gain_schedule_uses_the_dense_result(e: tuple[float, float], e_dot: tuple[float, float]) -> None:
    schedule = FuzzyPDGainSchedule()
    kp0, kp1, kd0, kd1 = schedule.step_floats(e[0], e[1], e_dot[0], e_dot[1])
    internals = schedule.internals
    inputs = [(internals["e_normalised"][j], internals["ce_normalised"][j]) for j in range(2)]
    fe0, fde0, fe1, fde1 = _dense_reference((pd_gain_system(TABLE_1), pd_gain_system(TABLE_7)), inputs)
    config = schedule.config
    expected = (
        config.kp0[0] + config.k1[0] * fe0,
        config.kp0[1] + config.k1[1] * fe1,
        config.kd0[0] + config.k2[0] * fde0,
        config.kd0[1] + config.k2[1] * fde1,
    )
    # The gains are k0 + k f with f in [-1, 1]: rounding is relative to k0.
    assert_allclose((kp0, kp1, kd0, kd1), expected, rtol=1e-15, atol=0.0)


def _no_general_path(*_: object) -> None:
    raise AssertionError("the general (rule by rule) path was taken")


def test_inputs_on_the_lattice_never_take_the_general_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every input pair within the peaks is evaluated from the 1, 2 or 4 rules around it (the hot path)."""
    systems = (pd_gain_system(TABLE_1, 51), pd_gain_system(TABLE_7, 51))
    reference = (pd_gain_system(TABLE_1, 51), pd_gain_system(TABLE_7, 51))
    batch = MamdaniBatch(systems)
    for system in systems:
        monkeypatch.setattr(system, "accumulate_strengths", _no_general_path)
    rng = np.random.default_rng(11)
    points = [*SPECIAL, *rng.uniform(-1.0, 1.0, 12)]
    points = [p for p in points if -1.0 <= p <= 1.0]
    for e, ce in zip(points, reversed(points), strict=True):
        for inputs in (((e, ce), (ce, e)), ((e, e), (0.51, ce))):
            assert_allclose(
                batch.evaluate_flat(inputs), _dense_reference(reference, inputs), rtol=0.0, atol=ATOL
            )


def test_single_input_within_the_means_never_takes_the_general_path(monkeypatch: pytest.MonkeyPatch) -> None:
    system = fleso_bandwidth_system(51)
    batch = MamdaniBatch([system, system])
    reference = fleso_bandwidth_system(51)
    monkeypatch.setattr(system, "accumulate_strengths", _no_general_path)
    for s in np.linspace(-1.0, 1.0, 41):
        inputs = ((float(s),), (float(-s),))
        assert_allclose(
            batch.evaluate_flat(inputs), _dense_reference((reference, reference), inputs), rtol=0.0, atol=ATOL
        )


def _fired_rules(system: MamdaniSystem, x: Sequence[float]) -> list[tuple[int, float]]:
    """(antecedent cell, AND = min of the degrees) of each rule firing at ``x``, from lattice_pair."""
    first, second = system.inputs
    pair_e, pair_ce = first.lattice_pair(x[0]), second.lattice_pair(x[1])
    assert pair_e is not None and pair_ce is not None
    (i, degree_i, degree_i1), (j, degree_j, degree_j1) = pair_e, pair_ce
    radix = len(second.labels)
    return [
        ((i + a) * radix + j + b, min(degree_a, degree_b))
        for a, degree_a in ((0, degree_i), (1, degree_i1))
        if degree_a > 0.0
        for b, degree_b in ((0, degree_j), (1, degree_j1))
        if degree_b > 0.0
    ]


_TABLES: dict[tuple[MamdaniSystem, int], LabelPairCentroids] = {}


def _label_table_reference(system: MamdaniSystem, fired: list[tuple[int, float]]) -> list[float]:
    """Each output's clipped labels (the max level per label) through LabelPairCentroids."""
    n_outputs, n_labels = len(system.outputs), system.n_labels
    concluded = [
        tuple(slot - o * n_labels for o, slot in enumerate(slots))
        for slots in system.slot_table(range(n_outputs * n_labels))
    ]
    weights = centroid_weights(system.grid)
    crisp = []
    for o in range(n_outputs):
        levels: dict[int, float] = {}
        for cell, level in fired:
            label = concluded[cell][o]
            levels[label] = max(levels.get(label, 0.0), level)
        key = (system, o)
        if key not in _TABLES:
            _TABLES[key] = LabelPairCentroids(system.output_samples[:, o, :], weights)
        table = _TABLES[key]
        if len(levels) == 1:
            crisp.append(table.single(*levels.popitem()))
        else:
            (a, level_a), (b, level_b) = levels.items()
            crisp.append(table.pair(a, level_a, b, level_b))
    return crisp


@settings(max_examples=200, deadline=None)
@given(
    on_peak=st.sampled_from([*PEAKS, -1.5, 1.5]),
    free=st.floats(-1.0, 1.0, allow_nan=False, allow_subnormal=True),
    peak_first=st.booleans(),
    other=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)),  # on the lattice too (else the dense path)
)
def test_one_or_two_rules_are_the_label_tables_of_lattice_pair_bit_for_bit(
    pd_systems: tuple[MamdaniSystem, MamdaniSystem],
    on_peak: float,
    free: float,
    peak_first: bool,
    other: tuple[float, float],
) -> None:
    """One input on a peak (or clipped to an end): 1 or 2 rules, each output from the label tables."""
    point = max(-1.0, min(1.0, on_peak))
    x = (point, free) if peak_first else (free, point)
    fired = _fired_rules(pd_systems[0], x)
    assume(len(fired) <= 2 and (len(fired) == 1 or abs(fired[0][1] + fired[1][1] - 1.0) <= 1e-9))
    crisp = MamdaniBatch(pd_systems).evaluate_flat((x, other))
    n_outputs = len(pd_systems[0].outputs)
    assert crisp[:n_outputs] == _label_table_reference(pd_systems[0], fired)
