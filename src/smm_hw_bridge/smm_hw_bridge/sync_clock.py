"""The CANopen master's SYNC clock in real time: the schedule, the SYNC counter, the late periods. Pure.

The host loop is the clock: slot k is due k periods after the first SYNC; a SYNC a period or more late takes
the latest slot due and carries the CiA 301 counter. Why and what counts as late: docs/HW_CANOPEN.md,
"Real time".
"""

from __future__ import annotations

from typing import Final

__all__ = ["COUNTER_OVERFLOW", "SyncClock", "periods_between"]

COUNTER_OVERFLOW: Final[int] = 240
"""The SYNC counter counts 1 .. this and starts again at 1 (CiA 301 0x1019, at most 240)."""


def periods_between(counter: int, last: int) -> int:
    """Periods from the SYNC whose counter was ``last`` to the one with ``counter`` (1 .. overflow)."""
    return (counter - last - 1) % COUNTER_OVERFLOW + 1


class SyncClock:
    """The schedule of SYNCs every ``period_ns`` (monotonic ns) from the first, and what each one ended.

    Args:
        period_ns: The SYNC period (ns), > 0.
    """

    def __init__(self, period_ns: int) -> None:
        if isinstance(period_ns, bool) or not isinstance(period_ns, int) or period_ns <= 0:
            raise ValueError(f"period_ns must be an int > 0, got {period_ns!r}")
        self.period_ns = period_ns
        self.start_ns: int | None = None
        self.slot = -1
        """The schedule slot of the last SYNC (0 for the first)."""
        self.due_ns = 0
        """When the next slot is due (0: at once)."""
        self.age = 1
        """Periods between the last SYNC and the one its latched setpoint answers (1 on time)."""
        self.late_periods = 0
        self._answer_ns: int | None = None

    @property
    def counter(self) -> int:
        """The last SYNC's counter (1 .. :data:`COUNTER_OVERFLOW`)."""
        return self.slot % COUNTER_OVERFLOW + 1

    def on_answer(self, now_ns: int) -> None:
        """The first command answering the last SYNC's feedback was written at ``now_ns``."""
        if self._answer_ns is None:
            self._answer_ns = now_ns

    def on_sync(self, now_ns: int, *, answered: bool) -> None:
        """A SYNC goes out at ``now_ns``; ``answered``: a command answered the last one's feedback."""
        start = self.start_ns
        if start is None:
            self.start_ns = start = now_ns
            slot, age = 0, 1  # nothing to answer yet: not judged
        else:
            slot = max(self.slot + 1, (now_ns - start) // self.period_ns)
            due = start + (self.slot + 1) * self.period_ns
            answer = self._answer_ns
            late_answer = not answered or answer is None or answer > due
            age = slot - self.slot + late_answer
            self.late_periods += age - 1
        self.slot, self.age, self._answer_ns = slot, age, None
        self.due_ns = start + (slot + 1) * self.period_ns
