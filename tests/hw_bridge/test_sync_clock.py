"""The CANopen master's SYNC clock in real time: the schedule, the counter, the late periods (times given)."""

from __future__ import annotations

import pytest
from smm_hw_bridge.sync_clock import COUNTER_OVERFLOW, SyncClock, periods_between

PERIOD = 5_000_000  # 200 Hz
START = 1_000_000_000


def _started() -> SyncClock:
    clock = SyncClock(PERIOD)
    clock.on_sync(START, answered=False)  # the first SYNC: nothing to answer yet, not judged
    return clock


def test_the_first_sync_is_slot_0_counter_1_and_the_next_is_due_a_period_later() -> None:
    clock = _started()
    assert (clock.slot, clock.counter, clock.age, clock.late_periods) == (0, 1, 1, 0)
    assert clock.due_ns == START + PERIOD


def test_an_answer_written_before_the_sync_was_due_is_on_time_even_if_the_sync_goes_out_late() -> None:
    clock = _started()
    due = clock.due_ns
    clock.on_answer(due - 100_000)
    clock.on_sync(due + 400_000, answered=True)  # the loop's wake-up jitter: the valves got the answer
    assert (clock.slot, clock.age, clock.late_periods) == (1, 1, 0)
    assert clock.due_ns == START + 2 * PERIOD  # the schedule does not drift with the jitter


@pytest.mark.parametrize(
    ("answer_after_due", "answered", "sync_after_due", "slot", "age"),
    [
        (1, True, 2, 1, 2),  # written after the SYNC was due: the valves held the last setpoint
        (None, False, 10, 1, 2),  # never answered (refused, or no answer)
        (-1, True, PERIOD, 2, 2),  # answered on time, the SYNC a whole period late: slot 1 skipped
        (-1, True, 3 * PERIOD + 7, 4, 4),  # a stall: three slots skipped, no burst of SYNCs after it
        (1, True, 3 * PERIOD, 4, 5),  # both
    ],
)
def test_late_periods_are_counted_and_the_age_says_what_the_valves_held(
    answer_after_due: int | None, answered: bool, sync_after_due: int, slot: int, age: int
) -> None:
    clock = _started()
    due = clock.due_ns
    if answer_after_due is not None:
        clock.on_answer(due + answer_after_due)
    clock.on_sync(due + sync_after_due, answered=answered)
    assert (clock.slot, clock.age, clock.late_periods) == (slot, age, age - 1)
    assert clock.due_ns == START + (slot + 1) * PERIOD


def test_the_first_answer_to_a_sync_counts_not_a_later_safe_frame() -> None:
    clock = _started()
    due = clock.due_ns
    clock.on_answer(due - 10)
    clock.on_answer(due + 10)
    clock.on_sync(due, answered=True)
    assert clock.age == 1


def test_the_counter_wraps_after_its_overflow_and_the_periods_between_follow_it() -> None:
    clock = _started()
    for slot in range(1, COUNTER_OVERFLOW + 2):
        clock.on_answer(clock.due_ns - 1)
        clock.on_sync(clock.due_ns, answered=True)
        assert clock.counter == slot % COUNTER_OVERFLOW + 1
    assert periods_between(1, COUNTER_OVERFLOW) == 1
    assert periods_between(5, 2) == 3
    assert periods_between(2, 5) == COUNTER_OVERFLOW - 3
    assert periods_between(7, 7) == COUNTER_OVERFLOW  # a whole turn (a longer stall aliases)


@pytest.mark.parametrize("period", [0, -1, 1.5, True, None])
def test_a_bad_period_is_refused(period: object) -> None:
    with pytest.raises(ValueError, match="period_ns"):
        SyncClock(period)  # type: ignore[arg-type]
