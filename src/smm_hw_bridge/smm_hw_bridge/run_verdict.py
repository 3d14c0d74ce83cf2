"""Whether a hardware run controlled: armed, live, few late periods (docs/LAUNCH.md, "Exit codes").

The board's feedback frames carry its status (``ENABLED``) and the age of the command on the valves; the
emulator (the frames it sends) and the bridge (the frames it admits) count them with :class:`RunTally`, so
both give the same figures. Late is counted per control period (docs/LAUNCH.md, "Control rate"); the limit
and its words are :mod:`smm_node_runtime.run_verdict`'s, which the real-time simulator judges by too.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

from smm_node_runtime.run_verdict import (
    EXIT_NOT_CONTROLLED,
    VerdictConfig,
    late_figures,
    late_fraction,
    late_reason,
)
from smm_schema.ranges import at_least

from smm_hw_bridge.protocol import FeedbackFrame, StatusBit, u32_diff

__all__ = ["EXIT_NOT_CONTROLLED", "HostVerdictConfig", "RunTally", "VerdictConfig"]

_ENABLED: Final[int] = int(StatusBit.ENABLED)


@dataclass(frozen=True)
class HostVerdictConfig(VerdictConfig):
    """The bridge's verdict: the late limit, and the run's planned length.

    Attributes:
        late_limit: Largest fraction of late control periods after ``settle_s`` (0.01 = 1 %).
        settle_s: Periods in the first ``settle_s`` seconds of live output are not judged (s).
        planned_s: The run's planned live length (s), 0 for none (a person ends it): a device fault after it
            (an emulated bench that ended its run falls silent) does not undo a run that controlled for it;
            one before it ends an autostarted run (exit 3: it cannot reach its plan without a person).
        ends_run: An autostarted run ends itself once ``planned_s`` are live (output disabled, judged): an
            external board or bench, which nothing else ends. Needs ``planned_s`` > 0.
    """

    planned_s: float = field(default=0.0, metadata=at_least(0.0))
    ends_run: bool = False

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.ends_run and not self.planned_s:
            raise ValueError("ends_run needs planned_s > 0 (the live seconds after which the run ends)")


class RunTally:
    """Counts a run's control periods and the late ones from the board's feedback frames, one call per frame.

    A control period is the N board ticks from one control tick (a multiple of N) to the next. It is late
    when the command answering its control tick was not on the valves by the next control tick: the
    feedback of that tick shows the output not live, or a command older than the period (``applied_age``
    above N). At N = 1 that is the board's late count: the answer to the last feedback had not arrived.

    Args:
        period_ns: The board's tick (ns), > 0.
        config: Limit and settling time.
        divider: N, board ticks per control period (``bridge.control_divider``), >= 1.
        every: Board ticks between two feedback frames: 1 (a board), N (a CANopen SYNC a period).
    """

    def __init__(
        self, period_ns: int, config: VerdictConfig | None = None, divider: int = 1, every: int = 1
    ) -> None:
        if period_ns <= 0:
            raise ValueError(f"period_ns must be > 0, got {period_ns!r}")
        if isinstance(divider, bool) or not isinstance(divider, int) or divider < 1:
            raise ValueError(f"divider must be an int >= 1, got {divider!r}")
        self.config = config or VerdictConfig()
        self.divider = divider
        self.every = every
        self.period_ns = period_ns
        self.period_ms = period_ns * divider / 1e6
        self.settle_ticks = round(self.config.settle_s * 1e9 / period_ns)
        self.armed = False
        """An enabled command was sent (bridge) or arrived (board)."""
        self.live_ticks = 0
        """Feedback frames with ENABLED set: ticks that latched or held an enabled command."""
        self.periods = 0
        """Control periods ending after the settling time from the first live tick on (the denominator)."""
        self.late_periods = 0
        """Of :attr:`periods`, those whose command was not on the valves by their end, or not live."""
        self.missed_ticks = 0
        """Ticks of which no feedback frame was counted here (lost on the way, or not read in time)."""
        self._first_live: int | None = None
        self._last: FeedbackFrame | None = None

    def on_feedback(self, frame: FeedbackFrame) -> None:
        """Counts one feedback frame (in tick order; a lost frame's periods are judged by the next one).

        After the settling time every period is judged at the feedback of the control tick that ends it.
        """
        last, self._last = self._last, frame
        if last is not None and last.session == frame.session:
            self.missed_ticks += max(0, u32_diff(frame.tick, last.tick) - self.every)
        enabled = bool(frame.status & _ENABLED)  # an int: IntFlag arithmetic costs a flag object
        if enabled:
            self.live_ticks += 1
            if self._first_live is None:
                self._first_live = frame.tick
        first = self._first_live
        if first is None or last is None:
            return
        ticks = u32_diff(frame.tick, last.tick)
        if last.session != frame.session or ticks <= 0:
            return  # a reboot, or the same tick re-sent (lockstep)
        divider = self.divider
        answered = frame.tick - frame.applied_age  # the tick the command on the valves answers
        dead_before = not last.status & _ENABLED  # frames lost after a frame not live: not live
        # the control ticks in (last.tick, frame.tick]: each ends the period that began N ticks before
        for end in range(frame.tick - (frame.tick % divider), frame.tick - ticks, -divider):
            if u32_diff(end, first) < self.settle_ticks:
                continue
            self.periods += 1
            seen = end == frame.tick
            if not enabled or (dead_before and not seen) or u32_diff(answered, end - divider) < 0:
                self.late_periods += 1

    def live_s(self) -> float:
        """Seconds from the first live tick to the last feedback counted (0 before the first live one)."""
        if self._first_live is None or self._last is None:
            return 0.0
        return (u32_diff(self._last.tick, self._first_live) + self.every) * self.period_ns / 1e9

    def before_plan(self, planned_s: float) -> bool:
        """True if the run is short of ``planned_s`` live (by more than a control period); always with 0."""
        return not planned_s or self.live_s() < planned_s - self.period_ms / 1e3

    @property
    def late_fraction(self) -> float:
        """Late share of the judged control periods (0 before any)."""
        return late_fraction(self.late_periods, self.periods)

    def figures(self) -> str:
        """``late L of N periods of T ms after the first S s live (P %), T live ticks in all``."""
        missed = f", {self.missed_ticks} ticks without a frame here" if self.missed_ticks else ""
        late = late_figures(self.late_periods, self.periods, self.period_ms, self.config)
        return f"{late}, {self.live_ticks} live ticks in all{missed}"

    def verdict(self) -> str | None:
        """Why the run did not control, or None if it did."""
        if not self.armed:
            return "the bridge never armed: no enabled command reached the board"
        if not self.live_ticks:
            return "the output never went live: no board tick latched an enabled command"
        return late_reason(self.late_periods, self.periods, self.config)
