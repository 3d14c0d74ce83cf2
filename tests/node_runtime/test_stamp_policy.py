"""Stamp gate and counters of smm_node_runtime (pure parts, no ROS graph)."""

from __future__ import annotations

import numpy as np
import pytest

from smm_node_runtime import COUNTER_ROWS, Admission, ControlPeriodConfig, InputCounters, StampGate


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
