"""Whether a hardware run controlled: armed, live, few late ticks (docs/LAUNCH.md, "Shutdown and exit codes").

The board's feedback frames carry its status (``ENABLED``) and its late count; the emulator (the frames it
sends) and the bridge (the frames it admits) count them with :class:`RunTally`, so both give the same figures.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

from smm_schema.ranges import at_least, bounds, check_bounds

from smm_hw_bridge.protocol import FeedbackFrame, StatusBit, u32_diff

__all__ = ["EXIT_NOT_CONTROLLED", "RunTally", "VerdictConfig"]

EXIT_NOT_CONTROLLED: Final[int] = 3
"""Exit code of a hardware run that did not control (never armed, never live, too many late ticks)."""


@dataclass(frozen=True)
class VerdictConfig:
    """When a run counts as controlled.

    Attributes:
        late_limit: Largest fraction of late enabled ticks after ``settle_s`` (0.01 = 1 %).
        settle_s: Enabled ticks in the first ``settle_s`` seconds of live output are not judged (s).
    """

    late_limit: float = field(default=0.01, metadata=bounds(0.0, 1.0))
    settle_s: float = field(default=1.0, metadata=at_least(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)


class RunTally:
    """Counts a run's enabled and late ticks from the board's feedback frames, one call per frame.

    Args:
        period_ns: The board's tick (ns), > 0.
        config: Limit and settling time.
    """

    def __init__(self, period_ns: int, config: VerdictConfig | None = None) -> None:
        if period_ns <= 0:
            raise ValueError(f"period_ns must be > 0, got {period_ns!r}")
        self.config = config or VerdictConfig()
        self.settle_ticks = round(self.config.settle_s * 1e9 / period_ns)
        self.armed = False
        """An enabled command was sent (bridge) or arrived (board)."""
        self.live_ticks = 0
        """Feedback frames with ENABLED set: ticks that latched an enabled command."""
        self.enabled_ticks = 0
        """Ticks after the settling time from the first live tick on (the late fraction's denominator)."""
        self.late_ticks = 0
        """Of :attr:`enabled_ticks`, those at which the board held the previous command (the answer to its
        last feedback had not arrived) or the output was not live."""
        self.missed_ticks = 0
        """Ticks of which no feedback frame was counted here (lost on the way, or not read in time)."""
        self._first_live: int | None = None
        self._last: FeedbackFrame | None = None

    def on_feedback(self, frame: FeedbackFrame) -> None:
        """Counts one feedback frame (in tick order; a lost frame's ticks count as the next one's).

        After the settling time every tick is judged: late if the board held the previous command, or if
        the output was not live (nulled by a watchdog, a fault, a disarm) at all.
        """
        last, self._last = self._last, frame
        if last is not None and last.session == frame.session:
            self.missed_ticks += max(0, u32_diff(frame.tick, last.tick) - 1)
        enabled = bool(frame.status & StatusBit.ENABLED)
        if enabled:
            self.live_ticks += 1
            if self._first_live is None:
                self._first_live = frame.tick
        first = self._first_live
        if first is None or last is None or u32_diff(frame.tick, first) < self.settle_ticks:
            return
        ticks = u32_diff(frame.tick, last.tick)
        if last.session != frame.session or ticks <= 0:
            return  # a reboot, or the same tick re-sent (lockstep)
        self.enabled_ticks += ticks
        if not enabled:
            self.late_ticks += ticks
        else:
            dead = ticks - 1 if not last.status & StatusBit.ENABLED else 0
            late = max(0, u32_diff(frame.late_commands, last.late_commands))
            self.late_ticks += min(ticks, dead + late)  # a missed tick is not late twice

    @property
    def late_fraction(self) -> float:
        """Late share of the judged enabled ticks (0 before any)."""
        return self.late_ticks / self.enabled_ticks if self.enabled_ticks else 0.0

    def figures(self) -> str:
        """``late L of N ticks after the first S s live (P %), T live ticks in all``."""
        missed = f", {self.missed_ticks} ticks without a frame here" if self.missed_ticks else ""
        return (
            f"late {self.late_ticks} of {self.enabled_ticks} ticks after the first "
            f"{self.config.settle_s:g} s live ({100.0 * self.late_fraction:.2f} %), "
            f"{self.live_ticks} live ticks in all{missed}"
        )

    def verdict(self) -> str | None:
        """Why the run did not control, or None if it did."""
        if not self.armed:
            return "the bridge never armed: no enabled command reached the board"
        if not self.live_ticks:
            return "the output never went live: no board tick latched an enabled command"
        if self.late_fraction > self.config.late_limit:
            return (
                f"{100.0 * self.late_fraction:.2f} % of the ticks after the first "
                f"{self.config.settle_s:g} s live were late or not live, above the limit of "
                f"{100.0 * self.config.late_limit:g} %"
            )
        return None
