"""First-order servo-valve lag of SPEC section 2: the valve's torque follows its command (pure, floats)."""

from __future__ import annotations

import math
from typing import Final

__all__ = [
    "PAPER_VALVE_RESPONSE_TIMES",
    "valve_lag_goal",
    "valve_lag_step",
    "valve_time_constants_from_response_times",
]

PAPER_VALVE_RESPONSE_TIMES: Final[tuple[float, float]] = (0.050, 0.025)
"""Servo-valve response time for a +-100 % step of the paper's Table 5 (rise, fall) (s)."""


def valve_time_constants_from_response_times(
    rise_time: float, fall_time: float, reached_fraction: float = 0.9
) -> tuple[float, float]:
    """Maps a valve's step response times to first-order lag time constants.

    A first-order lag reaches the fraction ``p`` of a step after ``-T ln(1 - p)``; the catalogue's
    response time is read as the time to ``reached_fraction`` (default 90 %).

    Args:
        rise_time: Response time while the valve opens (s), > 0.
        fall_time: Response time while the valve closes (s), > 0.
        reached_fraction: Fraction of the step reached at the response time, in (0, 1).

    Returns:
        (T_rise, T_fall) (s). For the paper's valve (50 ms, 25 ms): (21.7 ms, 10.9 ms).
    """
    for name, value in (("rise_time", rise_time), ("fall_time", fall_time)):
        if not math.isfinite(value) or value <= 0.0:
            raise ValueError(f"{name} must be a finite number > 0 s, got {value!r}")
    if not 0.0 < reached_fraction < 1.0:
        raise ValueError(f"reached_fraction must be in (0, 1), got {reached_fraction!r}")
    scale = -math.log(1.0 - reached_fraction)
    return rise_time / scale, fall_time / scale


def valve_lag_step(start: float, goal: float, h: float, rise: float, fall: float) -> tuple[float, float]:
    """One joint's valve torque after ``h`` s towards ``goal``, and its mean over those ``h`` s (N m).

    The valve opens (moves away from null, or starts at null) with time constant ``rise`` and closes
    (towards null or across it) with ``fall`` (s, > 0). Signs are compared, not multiplied: a product of
    two tiny torques underflows to 0.
    """
    time_constant = _lag_time_constant(start, goal, rise, fall)
    decay = math.exp(-h / time_constant)
    return goal + (start - goal) * decay, goal + (start - goal) * (time_constant / h) * (1.0 - decay)


def valve_lag_goal(start: float, end: float, h: float, rise: float, fall: float) -> float:
    """The goal that takes one joint's valve torque from ``start`` to ``end`` in ``h`` s (N m).

    The inverse of :func:`valve_lag_step`'s end value (the same opening / closing rule): the valve reaches
    ``end`` at the end of the step (deadbeat), the step amplified by 1 / (1 - exp(-h / T)).
    """
    reached = -math.expm1(-h / _lag_time_constant(start, end, rise, fall))  # the share of a step reached in h
    if reached == 0.0:  # h negligible against T: no finite goal gets there
        return start if end == start else math.copysign(math.inf, end - start)
    return start + (end - start) / reached


def _lag_time_constant(start: float, goal: float, rise: float, fall: float) -> float:
    """``rise`` when the valve opens (away from null, or from null), ``fall`` when it closes or crosses it."""
    return rise if start == 0.0 or (goal > start) == (start > 0.0) else fall
