"""What ``hw_bridge_node`` reports on ``/diagnostics``: the link, the board's counters and the host's."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from smm_node_runtime.health import Health, Level

from smm_hw_bridge.core import BridgeCore, BridgeState
from smm_hw_bridge.loop_statistics import LoopStatistics, RunningFigures
from smm_hw_bridge.protocol import Reason

__all__ = ["BridgeCounters", "bridge_health", "with_loop_figures"]


@dataclass
class BridgeCounters:
    """The node's own counts: commands taken and refused, frames sent, the last error."""

    commands: int = 0
    bad_commands: int = 0
    frames_sent: int = 0
    safe_frames_sent: int = 0
    last_error: str = ""
    refused: dict[str, int] = field(default_factory=dict)


def bridge_health(
    core: BridgeCore | None,
    counters: BridgeCounters,
    dropped: Mapping[str, int],
    *,
    host_fault: str,
    lifecycle: str,
    now_ns: int,
) -> Health:
    """The bridge's status; ``dropped``: the transport's drops by reason, ``now_ns`` monotonic (ns)."""
    values: dict[str, object] = {"lifecycle": lifecycle}
    if core is None:
        return Health(Level.OK, "unconfigured: no board link", values)
    last = core.last_feedback
    rtt = core.stats.rtt_percentiles_ns()
    link_up = core.link_up(now_ns)
    values.update(
        {
            "state": core.state.value,
            "link_up": link_up,
            "board_session": f"{core.board_session or 0:#010x}",
            "host_session": f"{core.host_session:#010x}",
            "feedback_received": core.stats.received,
            "packet_loss": f"{core.stats.loss_fraction:.6f}",
            "lost_frames": core.stats.lost,
            "longest_loss_streak": core.stats.longest_streak,
            "rtt_p50_ms": f"{rtt['p50'] / 1e6:.3f}",
            "rtt_p99_ms": f"{rtt['p99'] / 1e6:.3f}",
            "late_commands": 0 if last is None else last.late_commands,
            "board_crc_errors": 0 if last is None else last.crc_errors,
            "board_dropped_frames": 0 if last is None else last.dropped_frames,
            "fault_bits": f"{0 if last is None else last.faults:#06x}",
            "supply_pressure_bar": f"{core.supply_pressure_bar:.2f}",
            "watchdog_trips": core.watchdog_trips,
            "reboots": core.reboots,
            "commands": counters.commands,
            "bad_commands": counters.bad_commands,
            "frames_sent": counters.frames_sent,
            "safe_frames_sent": counters.safe_frames_sent,
        }
    )
    for reason in Reason:
        values[f"rejected_{reason.value}"] = core.rejected.get(reason, 0)
    for reason in (Reason.SOURCE, Reason.FRAMING):
        values[f"rejected_{reason.value}"] = core.rejected.get(reason, 0) + dropped.get(reason.value, 0)
    for why, count in counters.refused.items():
        values[f"refused_{why}"] = count
    if counters.last_error:
        values["last_error"] = counters.last_error
    state = core.state
    if host_fault:
        return Health(Level.ERROR, f"host fault: {host_fault}: valves at null", values)
    if state == BridgeState.FAULT:
        return Health(Level.ERROR, f"board fault bits {values['fault_bits']}: valves at null", values)
    if state == BridgeState.SESSION_LOST:
        return Health(Level.ERROR, "board rebooted or link lost: output disabled until re-activation", values)
    if not link_up:
        return Health(Level.ERROR, "link down: no valid feedback", values)
    if state == BridgeState.ESTOP:
        return Health(Level.WARN, "e-stop latched: re-arm to continue", values)
    return Health(Level.OK, f"{state.value}, link up", values)


def with_loop_figures(health: Health, statistics: LoopStatistics, publish_us: RunningFigures) -> Health:
    """``health`` plus the direct loop's periodicity and execution time (ros2_control's figures, us)."""
    values = {**health.values, **statistics.values()}
    values["publish_time.mean_us"] = f"{publish_us.mean:.1f}"
    values["publish_time.max_us"] = f"{publish_us.maximum:.1f}"
    return Health(health.level, health.message, values)
