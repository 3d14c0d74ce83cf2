"""Limits around the control law: plausibility of a measurement, and the output (torque) limiter.

Values and where they come from: ``docs/NODES.md`` (section "Limits"). Pure, no ROS.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Final, Protocol, runtime_checkable

from smm_schema.ranges import above, check_bounds

from smm_controller._validation import FloatArray, check_instance, internals_view

__all__ = [
    "DEFAULT_MAX_SPEED",
    "DEFAULT_POSITION_LIMIT",
    "DEFAULT_TORQUE_LIMIT",
    "MECHANICAL_STOPS",
    "POSITION_MARGIN",
    "MeasurementLimits",
    "OutputLimitConfig",
    "OutputLimiter",
    "PlausibilityCheck",
    "SaturationTracking",
    "track_saturation",
]

MECHANICAL_STOPS: Final[tuple[float, float]] = (1.3, 1.3)
"""The mechanical stops (alpha, beta) (rad): SPEC section 1 and smm_sim's default ``joint_limits``."""
POSITION_MARGIN: Final[float] = 0.2
"""Margin beyond the stops for encoder noise and stop compliance (rad); the limit stays below pi/2."""
DEFAULT_POSITION_LIMIT: Final[tuple[float, float]] = (
    MECHANICAL_STOPS[0] + POSITION_MARGIN,
    MECHANICAL_STOPS[1] + POSITION_MARGIN,
)
DEFAULT_MAX_SPEED: Final[tuple[float, float]] = (100.0, 100.0)
"""Largest plausible joint speed between two samples (rad/s): about 4 times the fastest of the reproduced
scenarios (27 rad/s, FPDESO step; 0.027 rad per 1 ms sample)."""
DEFAULT_TORQUE_LIMIT: Final[tuple[float, float]] = (300.0, 300.0)
"""Default torque limit (alpha, beta) (N m): just above the largest command of the reproduced scenarios
(288 N m, FPDESO step at t = 0), so the reproduction runs unclamped; the bench's actuator torque is not
published (SPEC section 2), so a bench sets its own."""


@dataclass(frozen=True)
class MeasurementLimits:
    """What a plausible position measurement is.

    Attributes:
        position_limit: Largest plausible |position| (alpha, beta) (rad), > 0: the mechanical stops (1.3 rad,
            SPEC section 1) plus a 0.2 rad margin.
        max_speed: Largest plausible speed between two samples (alpha, beta) (rad/s), > 0: a position may
            move at most this times the time between their stamps (at least one control period).
    """

    position_limit: tuple[float, float] = field(default=DEFAULT_POSITION_LIMIT, metadata=above(0.0))
    max_speed: tuple[float, float] = field(default=DEFAULT_MAX_SPEED, metadata=above(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)


class PlausibilityCheck:
    """Refuses positions outside the range or too far from the last accepted one (pure).

    Args:
        limits: The limits (default :class:`MeasurementLimits`).
    """

    def __init__(self, limits: MeasurementLimits | None = None) -> None:
        self.limits = limits if limits is not None else MeasurementLimits()
        self.reset()

    def reset(self) -> None:
        """Forget the last accepted measurement (the next is checked against the range only)."""
        self._last: tuple[int, float, float] | None = None

    def reconfigure(self, limits: MeasurementLimits) -> None:
        """Take new limits from the next check."""
        check_instance("limits", limits, MeasurementLimits)
        self.limits = limits

    def reason(self, position: tuple[float, float], stamp_ns: int, period_ns: int) -> str | None:
        """Why ``position`` (rad) at ``stamp_ns`` (ns) is implausible, or None when it is plausible.

        The step allowed since the last accepted stamp is ``max_speed`` times the time between the stamps, at
        least one period (``period_ns``, ns), so a genuine fast move is accepted again after a few samples.
        """
        limits = self.limits
        bound = limits.position_limit
        # Straight-line fast path (every step of the loop); the loops below only word the refusal.
        if not (abs(position[0]) <= bound[0] and abs(position[1]) <= bound[1]):
            for joint in range(2):
                if not abs(position[joint]) <= bound[joint]:
                    return f"position[{joint}] = {position[joint]!r} rad outside +-{bound[joint]} rad"
        last = self._last
        if last is None:
            return None
        elapsed_s = max(abs(stamp_ns - last[0]), period_ns) / 1e9
        speed = limits.max_speed
        moved = (position[0] - last[1], position[1] - last[2])
        if abs(moved[0]) <= speed[0] * elapsed_s and abs(moved[1]) <= speed[1] * elapsed_s:
            return None
        joint = 0 if abs(moved[0]) > speed[0] * elapsed_s else 1
        return (
            f"position[{joint}] moved {moved[joint]:+.6g} rad in {elapsed_s:.6g} s, "
            f"faster than {speed[joint]} rad/s"
        )

    def admit(self, position: tuple[float, float], stamp_ns: int, period_ns: int) -> str | None:
        """:meth:`reason`; a plausible ``position`` is also accepted (the next is checked against it)."""
        reason = self.reason(position, stamp_ns, period_ns)
        if reason is None:
            self.accept(position, stamp_ns)
        return reason

    def accept(self, position: tuple[float, float], stamp_ns: int) -> None:
        """Record ``position`` (rad) at ``stamp_ns`` (ns) as the last accepted measurement."""
        self._last = (stamp_ns, position[0], position[1])


@dataclass(frozen=True)
class OutputLimitConfig:
    """Limits on the torque command, applied after the law.

    Attributes:
        torque_limit: Largest |torque| (alpha, beta) (N m), > 0; inf = no limit. Default 300 N m: above the
            largest command of the reproduced scenarios (288 N m); set the bench actuator's own limit.
        rate_limit: Largest change of the torque per second (alpha, beta) (N m/s), > 0; inf = none (default).
    """

    torque_limit: tuple[float, float] = field(default=DEFAULT_TORQUE_LIMIT, metadata=above(0.0, inf=True))
    rate_limit: tuple[float, float] = field(default=(math.inf, math.inf), metadata=above(0.0, inf=True))

    def __post_init__(self) -> None:
        check_bounds(self)


@runtime_checkable
class SaturationTracking(Protocol):
    """A law with an integrator that must not wind up while its output is limited (e.g. the PID)."""

    def track_saturation(
        self, unlimited: tuple[float, float], limited: tuple[float, float], dt: float
    ) -> None:
        """Correct the integrator after the output ``unlimited`` was limited to ``limited`` (N m)."""


def track_saturation(
    law: object, unlimited: tuple[float, float], limited: tuple[float, float], dt: float
) -> None:
    """Tell ``law`` that its output was limited, if it tracks saturation (back-calculation anti-windup)."""
    if limited == unlimited:  # the common case, decided before the finiteness and protocol checks
        return
    finite = all(math.isfinite(value) for value in (*unlimited, *limited))
    if finite and isinstance(law, SaturationTracking):
        law.track_saturation(unlimited, limited, dt)


_INF = math.inf


class OutputLimiter:
    """Rate limit, then magnitude limit, of the torque command; counts and shows the clamps.

    Args:
        config: The limits (default :class:`OutputLimitConfig`).
    """

    def __init__(self, config: OutputLimitConfig | None = None) -> None:
        self.config = config if config is not None else OutputLimitConfig()
        self.reset()

    def reset(self) -> None:
        """Forget the previous output (no rate limit on the next step) and the clamp count."""
        self._previous: tuple[float, float] | None = None
        self._last = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self.clamps = 0
        """Steps in which at least one joint was limited."""

    def reconfigure(self, config: OutputLimitConfig) -> None:
        """Take new limits from the next step; the previous output and the count carry on."""
        check_instance("config", config, OutputLimitConfig)
        self.config = config

    def limit_floats(self, tau: tuple[float, float], dt: float) -> tuple[float, float]:
        """The limited command (N m) for the law's ``tau`` (N m), dt (s) since the previous one."""
        config = self.config
        previous = self._previous
        a, b = tau
        # Clamps inlined (every control step; -inf < x < inf is math.isfinite): a non-finite value passes
        # unclamped, so a diverged law fails the output check instead of becoming a full-scale torque.
        if previous is not None:
            rate_a, rate_b = config.rate_limit
            if -_INF < a < _INF:
                low, high = previous[0] - rate_a * dt, previous[0] + rate_a * dt
                a = low if a < low else (high if a > high else a)
            if -_INF < b < _INF:
                low, high = previous[1] - rate_b * dt, previous[1] + rate_b * dt
                b = low if b < low else (high if b > high else b)
        bound_a, bound_b = config.torque_limit
        if -_INF < a < _INF:
            a = -bound_a if a < -bound_a else (bound_a if a > bound_a else a)
        if -_INF < b < _INF:
            b = -bound_b if b < -bound_b else (bound_b if b > bound_b else b)
        result = (a, b)
        clamped_a = 0.0 if result[0] == tau[0] or math.isnan(result[0]) else 1.0
        clamped_b = 0.0 if result[1] == tau[1] or math.isnan(result[1]) else 1.0
        if clamped_a or clamped_b:
            self.clamps += 1
        self._previous = result
        self._last = (tau[0], tau[1], result[0], result[1], clamped_a, clamped_b)
        return result

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only, (2,): ``tau_unlimited``, ``tau`` (N m), ``clamped`` (1 where limited), ``clamps``."""
        clamps = float(self.clamps)
        return internals_view(("tau_unlimited", "tau", "clamped", "clamps"), (*self._last, clamps, clamps))
