"""The CANopen master's SYNC clock in real time: when each SYNC is due and which cycles were late. Pure.

The host loop is the clock (docs/HW_CANOPEN.md, "Real time"): its receiving thread sends each SYNC when it
is due, so a SYNC never overtakes the answer being computed; a cycle is late instead when that answer was
written after the SYNC was due, or the SYNC went out a whole period or more after it (the valves held the
last setpoint a period longer), as a frame board's period is late when the answer missed its next tick.
"""

from __future__ import annotations

__all__ = ["SyncClock"]


class SyncClock:
    """The schedule of SYNCs every ``period_ns`` (monotonic ns) and the late cycles.

    Args:
        period_ns: The SYNC period (ns), > 0.
    """

    def __init__(self, period_ns: int) -> None:
        if isinstance(period_ns, bool) or not isinstance(period_ns, int) or period_ns <= 0:
            raise ValueError(f"period_ns must be an int > 0, got {period_ns!r}")
        self.period_ns = period_ns
        self.due_ns = 0
        """When the next SYNC is due (0: at once)."""
        self.late = False
        """The last SYNC ended a late cycle."""
        self.cycles = 0
        """SYNCs sent on the schedule."""
        self.late_cycles = 0
        self.resynced = 0
        """Times the schedule restarted from now after a SYNC a whole period late (periods skipped)."""
        self._answer_ns: int | None = None

    def on_answer(self, now_ns: int) -> None:
        """The first command answering the last SYNC's feedback was written at ``now_ns``."""
        if self._answer_ns is None:
            self._answer_ns = now_ns

    def on_sync(self, now_ns: int, *, answered: bool) -> None:
        """A SYNC goes out at ``now_ns`` (>= :attr:`due_ns`); ``answered``: the last SYNC's feedback was."""
        due = self.due_ns
        answer = self._answer_ns
        behind = due > 0 and now_ns - due >= self.period_ns
        self.late = due > 0 and (not answered or answer is None or answer > due or behind)
        self.cycles += 1
        self.late_cycles += self.late
        self._answer_ns = None
        self.due_ns = (due or now_ns) + self.period_ns
        if self.due_ns <= now_ns:  # a stall: no burst of SYNCs to catch up, the schedule restarts
            self.due_ns = now_ns + self.period_ns
            self.resynced += 1
