"""Stamp gate and counters of smm_node_runtime (pure parts, no ROS graph)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from smm_node_runtime import (
    COUNTER_ROWS,
    REFUSED,
    Admission,
    ControlPeriodConfig,
    InputCounters,
    StampGate,
    StampPolicy,
)


def test_every_stamp_is_new_before_the_first_answer() -> None:
    gate = StampGate()
    assert gate.last_stamp_ns is None
    assert gate.classify(0) is Admission.NEW
    assert gate.classify(10**18) is Admission.NEW


@pytest.mark.parametrize(
    ("stamp", "expected"), [(99, Admission.STALE), (100, Admission.DUPLICATE), (101, Admission.NEW)]
)
def test_stamps_are_classified_against_the_last_answered(stamp: int, expected: Admission) -> None:
    gate = StampGate()
    gate.mark_answered(100)
    assert gate.classify(stamp) is expected


@pytest.mark.parametrize("stamp", [99, 100])
def test_answering_a_stamp_not_newer_than_the_last_is_a_bug(stamp: int) -> None:
    gate = StampGate()
    gate.mark_answered(100)
    with pytest.raises(ValueError, match="not newer"):
        gate.mark_answered(stamp)


def test_reset_makes_old_stamps_new_again() -> None:
    gate = StampGate()
    gate.mark_answered(100)
    gate.reset()
    assert gate.classify(5) is Admission.NEW


def test_counters_become_labelled_rows_with_the_count_in_both_columns() -> None:
    counters = InputCounters(dropped_invalid=3, dropped_stale=1, duplicates_answered=7)
    rows = counters.rows()
    assert tuple(rows) == COUNTER_ROWS
    np.testing.assert_array_equal(rows["dropped_invalid"], [3.0, 3.0])
    np.testing.assert_array_equal(rows["duplicates_answered"], [7.0, 7.0])
    np.testing.assert_array_equal(rows["invalid_outputs"], [0.0, 0.0])


@pytest.mark.parametrize("period", [0.0, -1e-3, float("inf"), float("nan"), True])
def test_control_period_must_be_positive_and_finite(period: float) -> None:
    with pytest.raises(ValueError, match="control_period"):
        ControlPeriodConfig(control_period=period)


# ---------------------------------------------------------------------------------- jumps (issue 12)

MS = 1_000_000
HOUR = 3_600 * 10**9


def answered_gate(*stamps: int, policy: StampPolicy | None = None) -> StampGate:
    gate = StampGate(policy, control_period=1e-3)
    for stamp in stamps:
        assert gate.classify(stamp) in (Admission.NEW, Admission.RESYNC)
        gate.mark_answered(stamp)
    return gate


def test_a_stamp_one_hour_ahead_is_refused_and_does_not_move_the_mark() -> None:
    gate = answered_gate(0, MS, 2 * MS)
    assert gate.classify(2 * MS + HOUR) is Admission.AHEAD
    assert gate.last_stamp_ns == 2 * MS
    assert gate.classify(3 * MS) is Admission.NEW  # the normal sequence goes on


def test_the_window_ahead_is_max_ahead_periods() -> None:
    gate = answered_gate(0, policy=StampPolicy(max_ahead_periods=10))
    assert gate.classify(10 * MS) is Admission.NEW
    assert gate.classify(10 * MS + 1) is Admission.AHEAD


@pytest.mark.parametrize(
    ("now_ns", "expected"), [(None, Admission.NEW), (0, Admission.NEW), (10**18, Admission.FUTURE)]
)
def test_a_stamp_ahead_of_the_node_clock_is_refused_unless_the_clock_is_unset(
    now_ns: int | None, expected: Admission
) -> None:
    gate = StampGate(StampPolicy(clock_tolerance=1.0))
    assert gate.classify(10**18 + 2 * 10**9, now_ns) is expected
    assert gate.classify(10**18 + 10**9, 10**18) is Admission.NEW  # within the tolerance


def test_a_backward_jump_is_believed_after_resync_samples_consistent_stamps() -> None:
    """Simulator restart / bag loop: stamps restart at 0 and go on; the old mark is forgotten."""
    gate = answered_gate(*(k * MS for k in range(5000, 5010)), policy=StampPolicy(resync_samples=4))
    results = [gate.classify(k * MS) for k in range(4)]
    assert results == [Admission.STALE] * 3 + [Admission.RESYNC]
    assert gate.last_stamp_ns is None
    assert gate.last_jump == (5009 * MS, 3 * MS)
    gate.mark_answered(3 * MS)
    assert gate.classify(4 * MS) is Admission.NEW


def test_a_lockstep_restart_resyncs_on_the_retransmitted_first_stamp() -> None:
    """A restarted lockstep simulator re-sends stamp 0 until it is answered: equal stamps are consistent."""
    gate = answered_gate(7 * MS, policy=StampPolicy(resync_samples=3))
    assert [gate.classify(0) for _ in range(3)] == [Admission.STALE, Admission.STALE, Admission.RESYNC]


def test_a_forward_jump_is_believed_after_resync_samples() -> None:
    gate = answered_gate(0, MS, policy=StampPolicy(resync_samples=3))
    results = [gate.classify(HOUR + k * MS) for k in range(3)]
    assert results == [Admission.AHEAD, Admission.AHEAD, Admission.RESYNC]


def test_stray_stamps_between_live_ones_never_resync() -> None:
    """A stray publisher interleaved with the live stream: every accepted stamp restarts the count."""
    gate = answered_gate(0, policy=StampPolicy(resync_samples=2))
    for k in range(1, 50):
        assert gate.classify(HOUR + k * MS) is Admission.AHEAD
        assert gate.classify(k * MS) is Admission.NEW
        gate.mark_answered(k * MS)
    assert gate.last_stamp_ns == 49 * MS


def test_inconsistent_refused_stamps_do_not_resync() -> None:
    gate = answered_gate(HOUR, policy=StampPolicy(resync_samples=3))
    # each refused stamp is far from the previous refused one: no track forms
    for k in range(20):
        assert gate.classify((k % 2) * 10 * HOUR + k * 10**9) in (Admission.STALE, Admission.AHEAD)
    assert gate.last_stamp_ns == HOUR


def test_a_stray_stamp_within_the_window_costs_at_most_resync_samples() -> None:
    """An accepted stray stamp moves the mark; the live stream behind it resyncs after resync_samples."""
    gate = answered_gate(0, 50 * MS, policy=StampPolicy(resync_samples=5))  # 50 ms: a stray, in the window
    results = [gate.classify(k * MS) for k in range(1, 6)]
    assert results == [Admission.STALE] * 4 + [Admission.RESYNC]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(min_value=0, max_value=2 * HOUR), max_size=60))
def test_refused_stamps_never_move_the_mark(stamps: list[int]) -> None:
    gate = answered_gate(HOUR)
    for stamp in stamps:
        before = gate.last_stamp_ns
        admission = gate.classify(stamp)
        if admission in REFUSED or admission is Admission.DUPLICATE:
            assert gate.last_stamp_ns == before
        elif admission is Admission.NEW:
            assert before is None or before < stamp <= before + gate.max_ahead_ns
            gate.mark_answered(stamp)
        else:
            assert gate.last_stamp_ns is None
            gate.mark_answered(stamp)


@pytest.mark.parametrize(
    ("field_name", "value"),
    [
        ("max_ahead_periods", 0),
        ("max_ahead_periods", 1.5),
        ("clock_tolerance", 0.0),
        ("resync_samples", 1),
        ("clock_tolerance", float("nan")),
    ],
)
def test_stamp_policy_bounds(field_name: str, value: object) -> None:
    with pytest.raises(ValueError, match=field_name):
        StampPolicy(**{field_name: value})  # type: ignore[arg-type]


def test_a_new_policy_or_period_applies_from_the_next_stamp() -> None:
    """The gate keeps its limits in ns; assigning a policy or a period recomputes them."""
    gate = StampGate(StampPolicy(max_ahead_periods=100, clock_tolerance=1.0), control_period=1e-3)
    gate.mark_answered(1_000_000)
    assert gate.classify(4_000_000) is Admission.NEW
    gate.policy = StampPolicy(max_ahead_periods=2, clock_tolerance=0.001)
    assert gate.max_ahead_ns == 2_000_000 and gate.classify(4_000_000) is Admission.AHEAD
    assert gate.classify(2_500_000, now_ns=1_000_000) is Admission.FUTURE
    gate.control_period = 2e-3
    assert gate.max_ahead_ns == 4_000_000 and gate.classify(4_000_000) is Admission.NEW
