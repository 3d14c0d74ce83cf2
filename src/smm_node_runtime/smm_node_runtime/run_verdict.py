"""Whether a real-time run controlled: the limit on late control periods and its words (pure).

Shared by the hardware path (``smm_hw_bridge.run_verdict.RunTally``, from the board's feedback frames) and
the real-time simulator (``smm_sim.core.SimCore``, from its ticks); docs/LAUNCH.md, "Shutdown and exit codes".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

from smm_schema.ranges import at_least, bounds, check_bounds

__all__ = ["EXIT_NOT_CONTROLLED", "VerdictConfig", "late_figures", "late_fraction", "late_reason"]

EXIT_NOT_CONTROLLED: Final[int] = 3
"""Exit code of a run that did not control (never live, too many late periods, zero torque)."""


@dataclass(frozen=True)
class VerdictConfig:
    """When a run counts as controlled.

    Attributes:
        late_limit: Largest fraction of late control periods after ``settle_s`` (0.01 = 1 %).
        settle_s: Periods in the first ``settle_s`` seconds of live output are not judged (s).
    """

    late_limit: float = field(default=0.01, metadata=bounds(0.0, 1.0))
    settle_s: float = field(default=1.0, metadata=at_least(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)


def late_fraction(late: int, periods: int) -> float:
    """Late share of the judged control periods (0 before any)."""
    return late / periods if periods else 0.0


def late_figures(late: int, periods: int, period_ms: float, config: VerdictConfig) -> str:
    """``late L of N periods of T ms after the first S s live (P %)``."""
    return (
        f"late {late} of {periods} periods of {period_ms:g} ms after the first {config.settle_s:g} s live "
        f"({100.0 * late_fraction(late, periods):.2f} %)"
    )


def late_reason(late: int, periods: int, config: VerdictConfig) -> str | None:
    """Why ``late`` of ``periods`` judged periods mean the run did not control, or None within the limit."""
    fraction = late_fraction(late, periods)
    if fraction <= config.late_limit:
        return None
    return (
        f"{100.0 * fraction:.2f} % of the control periods after the first {config.settle_s:g} s live were "
        f"late or not live, above the limit of {100.0 * config.late_limit:g} %"
    )
