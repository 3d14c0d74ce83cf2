"""Tracking differentiator (TD, paper eq. 24-25), one per joint, applied to the measured position.

x1 tracks the input v (rad), x2 is its derivative (rad/s); ``step`` returns x1(k+1), x2(k+1). fst is
eq. 25 with two misprints corrected as in Han's ``fhan`` (:func:`fhan`); the filter factor h must be
>= dt; the first step starts at x1 = v, x2 = 0 (docs/DESIGN.md, "Tracking differentiator").
"""

from __future__ import annotations

import math
import types
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from smm_schema.ranges import above, check_bounds

from smm_controller._validation import (
    FloatArray,
    as_joint_vector,
    check_dt,
    check_instance,
    readonly_copies,
)

__all__ = [
    "DEFAULT_TD_FILTER_FACTOR",
    "DEFAULT_TD_SPEED",
    "TrackingDifferentiator",
    "TrackingDifferentiatorConfig",
    "fhan",
    "fst",
]

#: Speed factor sigma per joint (rad/s^2). For |y| < h^2 sigma the TD is a linear second-order filter
#: with natural frequency 1/h, so sigma only matters for large jumps. Case-2 RMS is the same within 0.1 %
#: for sigma in [1e4, 1e6] (``python -m smm_analysis.reproduction.tune_td``); 1e5 is the middle.
DEFAULT_TD_SPEED: tuple[float, float] = (1.0e5, 1.0e5)
#: Filter factor h per joint (s), >= the control period: h = t = 1 ms, where eq. 25 equals Han's fhan.
#: With the observer's velocity (the default) the TD feeds only the position. Case-2 RMS (mrad): 9.06 /
#: 4.62 at 1 ms, 7.76 / 4.15 at 1.5 ms, 7.80 / 4.49 at 2 ms, 12.4 / 8.9 at 5 ms; above 1.5 ms the phase lag
#: grows RMS and overshoot, and the baselines share the TD, so h stays at t. docs/REPRODUCTION.md, "The
#: chosen defaults and why".
DEFAULT_TD_FILTER_FACTOR: tuple[float, float] = (0.001, 0.001)


@dataclass(frozen=True)
class TrackingDifferentiatorConfig:
    """Parameters of the tracking differentiator, per joint (alpha, beta).

    Attributes:
        speed: sigma, the tracking speed factor (rad/s^2), > 0.
        filter_factor: h, the filter factor (s), > 0; must also be >= dt at run time.
    """

    speed: tuple[float, float] = field(default=DEFAULT_TD_SPEED, metadata=above(0.0))
    filter_factor: tuple[float, float] = field(default=DEFAULT_TD_FILTER_FACTOR, metadata=above(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)


def fhan(x1: float, x2: float, r: float, h0: float) -> float:
    """Han's time-optimal synthesis function fhan in its common form (y = x1 + h0 x2).

    Args:
        x1: Tracking error x1 - v (rad).
        x2: Derivative state (rad/s).
        r: Speed factor (rad/s^2), > 0.
        h0: Filter factor (s), > 0.

    Returns:
        The acceleration command (rad/s^2), in [-r, r].
    """
    d = r * h0
    d0 = h0 * d
    y = x1 + h0 * x2
    a = x2 + (math.copysign(0.5 * (math.sqrt(d * d + 8.0 * r * abs(y)) - d), y) if abs(y) > d0 else y / h0)
    return -r * math.copysign(1.0, a) if abs(a) > d else -r * a / d


def fst(e: float, x2: float, sigma: float, h: float, t: float) -> float:
    """Synthesis function of eq. 25 (y = e + t x2; see the module docstring for the corrections).

    Args:
        e: Tracking error x1(k) - v(k) (rad).
        x2: Derivative state x2(k) (rad/s).
        sigma: Speed factor (rad/s^2), > 0.
        h: Filter factor (s), > 0.
        t: Integration step (s), > 0.

    Returns:
        The acceleration command (rad/s^2), in [-sigma, sigma].
    """
    delta = h * sigma
    delta1 = h * delta
    y = e + t * x2
    if abs(y) < delta1:
        g = x2 + y / h
    else:
        g = x2 + math.copysign(0.5 * (math.sqrt(8.0 * sigma * abs(y) + delta * delta) - delta), y)
    return -sigma * (g / delta if abs(g) < delta else math.copysign(1.0, g))


class TrackingDifferentiator:
    """Two independent tracking differentiators (alpha, beta), eq. 24-25.

    Args:
        config: Speed and filter factors per joint.
    """

    def __init__(self, config: TrackingDifferentiatorConfig | None = None) -> None:
        self.config = config if config is not None else TrackingDifferentiatorConfig()
        self._sigma = self.config.speed
        self._h = self.config.filter_factor
        self.reset()

    def reset(self) -> None:
        """Forgets the state; the next step re-initialises x1 to its input and x2 to 0."""
        self._initialised = False
        self._x1 = [0.0, 0.0]
        self._x2 = [0.0, 0.0]
        self._input = [0.0, 0.0]

    def reconfigure(self, config: TrackingDifferentiatorConfig) -> None:
        """Takes a new config for the next step and keeps the state (x1, x2, last input).

        A live gain change therefore does not restart the velocity estimate at 0; the next step integrates
        from the current (x1, x2) with the new sigma and h.

        Args:
            config: The new speed and filter factors (replaces the config whole).

        Raises:
            TypeError: ``config`` is not a :class:`TrackingDifferentiatorConfig`.
        """
        self.config = check_instance("config", config, TrackingDifferentiatorConfig)
        self._sigma = config.speed
        self._h = config.filter_factor

    def step(self, v: npt.ArrayLike, dt: float) -> tuple[FloatArray, FloatArray]:
        """Advances both TDs by one step of length dt.

        Args:
            v: Measured position (alpha, beta) (rad), shape (2,).
            dt: Step size t (s), > 0 and <= every filter factor h.

        Returns:
            (x1, x2): tracked position (rad) and its derivative (rad/s), each shape (2,).
        """
        check_dt(dt)
        v0, v1 = as_joint_vector("v", v)
        x1a, x1b, x2a, x2b = self.step_floats(v0, v1, dt)
        return np.array((x1a, x1b)), np.array((x2a, x2b))

    def step_floats(self, v0: float, v1: float, dt: float) -> tuple[float, float, float, float]:
        """Same as :meth:`step` on plain floats: returns (x1_alpha, x1_beta, x2_alpha, x2_beta)."""
        h0, h1 = self._h
        if h0 < dt or h1 < dt:
            raise ValueError(f"filter_factor {self._h!r} must be >= dt = {dt!r} s")
        x1 = self._x1
        x2 = self._x2
        self._input[0] = v0
        self._input[1] = v1
        if not self._initialised:
            x1[0] = v0
            x1[1] = v1
            x2[0] = 0.0
            x2[1] = 0.0
            self._initialised = True
        sigma0, sigma1 = self._sigma
        accel0 = fst(x1[0] - v0, x2[0], sigma0, h0, dt)
        accel1 = fst(x1[1] - v1, x2[1], sigma1, h1, dt)
        x1[0] += dt * x2[0]
        x1[1] += dt * x2[1]
        x2[0] += dt * accel0
        x2[1] += dt * accel1
        return x1[0], x1[1], x2[0], x2[1]

    def next_position(self, dt: float) -> tuple[float, float] | None:
        """x1 after the next step of length ``dt`` (rad), None before the first step.

        It needs no measurement: eq. 24 moves x1 with the previous x2.
        """
        if not self._initialised:
            return None
        x1, x2 = self._x1, self._x2
        return x1[0] + dt * x2[0], x1[1] + dt * x2[1]

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only copies: x1 (rad), x2 (rad/s), input (rad), each shape (2,)."""
        return types.MappingProxyType(readonly_copies({"x1": self._x1, "x2": self._x2, "input": self._input}))
