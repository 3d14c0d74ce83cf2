"""The bridge process's start and end: what ``autostart`` waits for, the exit code of its run. No ROS."""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from typing import Protocol

from smm_schema.ranges import at_least, check_bounds

from smm_hw_bridge.core import BridgeCore
from smm_hw_bridge.loop_statistics import LoopStatistics
from smm_hw_bridge.preflight import EXIT_PREFLIGHT_REFUSED
from smm_hw_bridge.run_verdict import EXIT_NOT_CONTROLLED, RunTally

__all__ = ["AutostartGate", "JudgedRun", "closing_line", "judged_exit", "realtime_scheduled", "run_verdict"]


@dataclass(frozen=True)
class AutostartGate:
    """What ``autostart`` waits for besides a ``torque_command`` publisher.

    Attributes:
        autostart_subscribers: ``joint_states`` subscriptions (the controller, a recorder), so that a
            recording has the first step.
    """

    autostart_subscribers: int = field(default=0, metadata=at_least(0))

    def __post_init__(self) -> None:
        check_bounds(self)


class JudgedRun(Protocol):
    """What the exit code is judged from (the bridge node)."""

    autostart: bool
    preflight_refusal: str | None

    def run_verdict(self) -> str | None:
        """Why the run did not control, None if it did."""


def run_verdict(tally: RunTally | None, core: BridgeCore | None, *, waited: bool) -> str | None:
    """Why a run did not control (never configured, never armed, ...), None if it did.

    Args:
        tally: The run's tally, None before the first configure.
        core: The last session's core (its refused commands), or None.
        waited: ``autostart`` still waited for the controller.
    """
    if tally is None:
        if waited:
            return "the bridge never armed: autostart waited for the controller to the end"
        return "the bridge was never configured: no valid feedback from the board"
    reason = tally.verdict()
    if reason is not None and not tally.armed and core is not None and core.refused:
        refused = ", ".join(f"{why.value} {count}" for why, count in sorted(core.refused.items(), key=str))
        reason += f" (commands refused: {refused})"
    return reason


def closing_line(
    tally: RunTally | None, reason: str | None, refusal: str | None, statistics: LoopStatistics | None
) -> str:
    """The closing line: the run's figures and verdict; ``statistics``: the direct loop's receive -> send."""
    if refusal is not None:
        line = "host: refused to arm at preflight (its figures and reason above); no output went live"
    elif tally is None:
        line = f"host: no feedback frame counted; did not control: {reason}"
    else:
        verdict = "controlled" if reason is None else f"did not control: {reason}"
        line = f"host: {tally.figures()}, from the board's feedback frames; {verdict}"
    if statistics is None:
        return line
    return (
        f"{line}; receive->send p50 {statistics.execution_percentile_us(50):.0f} us, "
        f"p99 {statistics.execution_percentile_us(99):.0f} us, max {statistics.execution_us.maximum:.0f} us "
        f"over {statistics.execution_us.count} commands"
    )


def realtime_scheduled() -> bool:
    """True when this process runs under a real-time policy (SCHED_FIFO or SCHED_RR)."""
    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)
    except (AttributeError, OSError):  # not Linux
        return False


def judged_exit(code: int, node: JudgedRun | None, name: str) -> int:
    """``code``, or :data:`EXIT_NOT_CONTROLLED` when ``node`` was to start itself and its run did not control.

    A bridge driven by hand (no ``autostart``) is not judged: the closing line says what it saw.
    """
    if code != 0 or node is None or not node.autostart:
        return code
    if node.preflight_refusal is not None:
        print(f"{name}: refused to arm at preflight: {node.preflight_refusal}", file=sys.stderr, flush=True)
        return EXIT_PREFLIGHT_REFUSED
    reason = node.run_verdict()
    if reason is None:
        return code
    print(f"{name}: the run did not control: {reason}", file=sys.stderr, flush=True)
    return EXIT_NOT_CONTROLLED
