"""The bridge's safety stop (pure): a joint past its soft limit by a margin, or running away from its torque.

Both catch a bench whose valve or encoder runs the other way than the bridge assumes, which the soft limit's
cut cannot hold (docs/HW_PROTOCOL.md, section 10, "safety stop").
"""

from __future__ import annotations

from dataclasses import dataclass, field

from smm_schema.ranges import bounds, check_bounds

__all__ = ["SafetyStop", "SafetyStopConfig"]

_JOINTS = ("alpha", "beta")
_CHECK = (
    "check bridge.valve.polarity and bridge.encoder.direction / zero_offset against the bench (a valve or an "
    "encoder running the other way, or an encoder zero elsewhere)"
)


@dataclass(frozen=True)
class SafetyStopConfig:
    """When the bridge stops a run (``bridge.limit_stop.*``).

    Attributes:
        margin: A joint past its soft limit by more than this while arming or armed is a safety stop (rad),
            in (0, 1]: the soft limit's cut cannot hold a joint whose valve or encoder runs the other way.
        lead: The margin judges the position this far ahead at the measured speed (s), in [0, 1]:
            q + q' * lead, q' over the last two admitted feedbacks.
        runaway_torque: The smallest torque the valve gives (the bridge's model of the codes the board
            reports) that the runaway check judges (N m), > 0; above the torques the bridge does not model
            (gravity, friction, the joints' coupling).
        runaway_acceleration: A joint accelerating against that torque by more than this, on every tick of
            ``runaway_window``, is a safety stop (rad/s^2), > 0.
        runaway_window: Span of the acceleration estimate, (q_t - 2 q_(t-k) + q_(t-2k)) / (k h)^2 over 2k
            ticks of h (s), in [0, 1]; the torque must keep its sign and size over the span, and the joint
            accelerate against it for as long again (one jump of speed, an impact on a stop, moves the
            estimate for fewer ticks). 0 = no runaway check.
    """

    margin: float = field(default=0.15, metadata=bounds(1e-6, 1.0))
    lead: float = field(default=0.0, metadata=bounds(0.0, 1.0))
    runaway_torque: float = field(default=2.0, metadata=bounds(1e-6, 1e6))
    runaway_acceleration: float = field(default=60.0, metadata=bounds(1e-6, 1e9))
    runaway_window: float = field(default=0.02, metadata=bounds(0.0, 1.0))

    def __post_init__(self) -> None:
        check_bounds(self)


class SafetyStop:
    """Judges each admitted feedback of a live output; :meth:`reason` says why the run must stop, or None.

    Args:
        config: When to stop.
        soft_limits: The bridge's soft limits (alpha, beta) (rad).
        period_ns: Board tick (ns).
    """

    def __init__(self, config: SafetyStopConfig, soft_limits: tuple[float, float], period_ns: int) -> None:
        self._config = config
        self._limits = (float(soft_limits[0]), float(soft_limits[1]))
        self._stops = (self._limits[0] + config.margin, self._limits[1] + config.margin)
        self._lead_ticks = config.lead * 1e9 / period_ns
        half = round(config.runaway_window * 1e9 / period_ns / 2)
        self._k = max(half, 1) if config.runaway_window > 0.0 else 0
        self._span_s = self._k * period_ns * 1e-9
        self.reset()

    def reset(self) -> None:
        """Forgets everything (a new session)."""
        self._position = (0.0, 0.0)
        self._previous: tuple[int, tuple[float, float]] | None = None
        """Tick and angles of the feedback before the last."""
        self._last_tick_any: int | None = None
        self._tick = 0
        self.arm()

    def arm(self) -> None:
        """Forgets the runaway check's history and verdict (an activation); the last angles stay judged."""
        self._positions: list[tuple[float, float]] = [(0.0, 0.0)] * (2 * self._k + 1)
        self._filled = 0
        """Consecutive live ticks in ``_positions``, up to its length."""
        self._live_tick: int | None = None
        self._pushing: list[int | None] = [None, None]
        """Per joint, the tick since which the torque has kept its sign and size (runaway_torque)."""
        self._effort_sign = [0.0, 0.0]
        self._since: list[int | None] = [None, None]
        """Per joint, the tick since which it has accelerated against that torque."""
        self._runaway: str | None = None

    def on_feedback(
        self,
        tick: int,
        position: tuple[float, float],
        effort: tuple[float, float],
        live: bool,
    ) -> None:
        """Judges one admitted feedback.

        Args:
            tick: Its unwrapped board tick.
            position: Joint angles (alpha, beta) (rad).
            effort: The valves' torque over the tick before it (N m), the bridge's model of the codes.
            live: Whether the output was live.
        """
        self._previous = None if self._last_tick_any is None else (self._last_tick_any, self._position)
        self._tick, self._position, self._last_tick_any = tick, position, tick
        k = self._k
        if k == 0 or self._runaway is not None:
            return
        if not live or self._live_tick is None or tick != self._live_tick + 1:
            self._filled, self._pushing, self._since = 0, [None, None], [None, None]
        self._live_tick = tick if live else None
        if not live:
            return
        size = 2 * k + 1
        self._positions[tick % size] = position
        self._filled = min(self._filled + 1, size)
        floor = self._config.runaway_torque
        for joint in range(2):
            torque = effort[joint]
            pushing = self._pushing[joint]
            if abs(torque) < floor:
                self._pushing[joint] = self._since[joint] = None
                continue
            if pushing is None or torque * self._effort_sign[joint] < 0.0:
                self._pushing[joint], self._since[joint] = tick, None
                self._effort_sign[joint] = torque
                continue
            if tick - pushing + 1 < 2 * k or self._filled < size:
                continue
            q = position[joint]
            middle = self._positions[(tick - k) % size][joint]
            first = self._positions[(tick - 2 * k) % size][joint]
            acceleration = (q - 2.0 * middle + first) / (self._span_s * self._span_s)
            if acceleration * torque >= -self._config.runaway_acceleration * abs(torque):
                self._since[joint] = None
                continue
            since = self._since[joint]
            if since is None:
                self._since[joint] = since = tick
            if tick - since + 1 >= 2 * k:
                self._runaway = self._describe(joint, acceleration, torque)
                return

    def _describe(self, joint: int, acceleration: float, torque: float) -> str:
        config = self._config
        return (
            f"safety stop: joint {_JOINTS[joint]} accelerates at {acceleration:.0f} rad/s^2 against the "
            f"{torque:+.2f} N m its valve gives, for {2 * self._span_s * 1e3:.0f} ms "
            f"(bridge.limit_stop.runaway_acceleration {config.runaway_acceleration:g} rad/s^2, "
            f"runaway_torque {config.runaway_torque:g} N m, runaway_window {config.runaway_window:g} s): "
            f"{_CHECK}"
        )

    def reason(self) -> str | None:
        """Why the run must stop (a runaway, or a joint past soft limit + margin), or None."""
        if self._runaway is not None:
            return self._runaway
        previous = self._previous
        lead = 0.0 if previous is None else self._lead_ticks / max(self._tick - previous[0], 1)
        for joint, (position, stop) in enumerate(zip(self._position, self._stops, strict=True)):
            ahead = position if previous is None else position + (position - previous[1][joint]) * lead
            if abs(ahead) > stop:
                config = self._config
                return (
                    f"safety stop: joint {_JOINTS[joint]} reads {position:.3f} rad ({ahead:.3f} rad "
                    f"bridge.limit_stop.lead {config.lead:g} s ahead), past its soft limit "
                    f"{self._limits[joint]:g} rad by more than bridge.limit_stop.margin {config.margin:g} "
                    f"rad: {_CHECK}"
                )
        return None
