"""Torque -> D/A code (gain per direction, deadband, null bias, saturation, rate limit); and back, lagged."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Final, Literal, get_args

import numpy as np
import numpy.typing as npt
from smm_dynamics.valve import (
    PAPER_VALVE_RESPONSE_TIMES,
    valve_lag_goal,
    valve_lag_step,
    valve_time_constants_from_response_times,
)
from smm_schema.ranges import above, at_least, bounds, check_bounds

from smm_hw_bridge.protocol import CODE_MAX

__all__ = ["LAG_COMPENSATION", "OutputSample", "ValveOutput", "ValveOutputConfig"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
PAPER_TIME_CONSTANTS = valve_time_constants_from_response_times(*PAPER_VALVE_RESPONSE_TIMES)
"""(T_rise, T_fall) of the paper's servo valve (s)."""
LagCompensation = Literal["auto", "on", "off"]
LAG_COMPENSATION: Final[tuple[str, ...]] = get_args(LagCompensation)
"""Values of :attr:`ValveOutputConfig.lag_compensation`."""


@dataclass(frozen=True)
class ValveOutputConfig:
    """Mapping of a joint torque command to the valve's D/A code.

    Attributes:
        gain: D/A codes per N m of joint torque (alpha, beta), > 0; of a positive torque when
            ``gain_negative`` is set.
        gain_negative: D/A codes per N m of a negative joint torque (alpha, beta), >= 0; 0 = ``gain`` (the
            valve gives the same torque both ways, and a parameter file without it keeps its meaning).
        polarity: +1 if a positive code drives q positive, -1 if negative (alpha, beta).
        deadband: Valve overlap as a D/A code (alpha, beta), >= 0: a code of magnitude below it moves
            nothing, so a non-zero demand is offset by it.
        null_bias: D/A code at which the valve's spool is at null (alpha, beta), in [-32767, 32767]: added
            to every code after the deadband offset; |null_bias| + deadband must stay below code_limit.
        deadband_blend: Demand (codes) below which the offset is blended in linearly, > 0, so the map is
            continuous through zero.
        code_limit: Saturation of |code| (alpha, beta), in [1, 32767].
        rate_limit: Largest code change per second (alpha, beta), > 0; ``inf`` = off. Default: full scale
            in 2 ms, a tenth of the valve's own opening time. Full scale in 20 ms made the FPDESO loop
            unstable on the emulated bench (docs/LAUNCH.md, "Measured: the hardware path").
        time_constants: (T_rise, T_fall) of the valves' first-order lag (s), both > 0, or (0, 0) for none:
            the model by which :meth:`ValveOutput.effort` turns the codes on the valves into the torque they
            give (the board cannot measure it). Default: the paper's valve (SPEC section 2).
        lag_compensation: Drive the valves through the inverse of that lag: each command's code is the goal
            that brings the modelled valve torque to the demand by the end of the command's period (deadbeat;
            :func:`~smm_dynamics.valve.valve_lag_goal`). "auto": at control periods longer than one board
            tick (``bridge.control_divider`` > 1), where the lag breaks the FPDESO loop (docs/LAUNCH.md,
            "Control rate"); "on": at every period; "off": never. Nothing without a lag model.
    """

    gain: tuple[float, float] = field(default=(CODE_MAX / 10.0, CODE_MAX / 10.0), metadata=above(0.0))
    gain_negative: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    polarity: tuple[int, int] = field(default=(1, 1), metadata=bounds(-1, 1))
    deadband: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    null_bias: tuple[float, float] = field(default=(0.0, 0.0), metadata=bounds(-CODE_MAX, CODE_MAX))
    deadband_blend: float = field(default=50.0, metadata=bounds(1e-3, 32767.0))
    code_limit: tuple[int, int] = field(default=(CODE_MAX, CODE_MAX), metadata=bounds(1, CODE_MAX))
    rate_limit: tuple[float, float] = field(
        default=(CODE_MAX / 0.002, CODE_MAX / 0.002), metadata=above(0.0, inf=True)
    )
    time_constants: tuple[float, float] = field(
        default=valve_time_constants_from_response_times(*PAPER_VALVE_RESPONSE_TIMES), metadata=at_least(0.0)
    )
    lag_compensation: LagCompensation = "auto"

    def __post_init__(self) -> None:
        check_bounds(self)
        if 0 in self.polarity:
            raise ValueError(f"polarity must be +1 or -1 per joint, got {self.polarity!r}")
        if any(self.deadband[j] + abs(self.null_bias[j]) >= self.code_limit[j] for j in range(2)):
            raise ValueError(
                f"deadband {self.deadband!r} plus |null_bias| {self.null_bias!r} must be below code_limit "
                f"{self.code_limit!r}"
            )
        if (self.time_constants[0] == 0.0) != (self.time_constants[1] == 0.0):
            raise ValueError(
                f"time_constants must be both > 0 or both 0 (no lag), got {self.time_constants!r}"
            )
        if self.lag_compensation not in LAG_COMPENSATION:
            raise ValueError(
                f"lag_compensation must be one of {', '.join(LAG_COMPENSATION)}, "
                f"got {self.lag_compensation!r}"
            )

    def compensates_lag(self, control_divider: int) -> bool:
        """True if the valves are driven through their lag's inverse at ``control_divider`` ticks a period."""
        if self.time_constants[0] == 0.0 or self.lag_compensation == "off":
            return False
        return self.lag_compensation == "on" or control_divider > 1


@dataclass(frozen=True)
class OutputSample:
    """One mapped command.

    Attributes:
        codes: D/A codes sent (alpha, beta).
        torque: Torque those codes command (N m), shape (2,): the demand (its lag goal when compensated)
            after clamping and rounding.
        clamped: Per joint, True if saturation or the rate limit changed the demand, shape (2,).
    """

    codes: tuple[int, int]
    torque: FloatArray
    clamped: BoolArray


def _rint(value: float) -> float:
    """``np.rint`` of a finite float: round half to even, the sign of a zero result kept."""
    rounded = float(round(value))
    return rounded if rounded != 0.0 else math.copysign(0.0, value)


class ValveOutput:
    """Maps torque demands to D/A codes, one call per sent command (the rate limit is per call's ``dt``).

    Python floats per joint (numpy on 2-element arrays costs more than the arithmetic); the arrays of
    :attr:`last` and :attr:`internals` are built when read. ``control_divider``: board ticks a command
    (``bridge.control_divider``), which decides ``lag_compensation`` "auto".
    """

    def __init__(self, config: ValveOutputConfig, control_divider: int = 1) -> None:
        self._config = config
        self._compensate = config.compensates_lag(control_divider)
        self._gain = (
            float(config.gain[0]) * float(config.polarity[0]),
            float(config.gain[1]) * float(config.polarity[1]),
        )
        negative = tuple(config.gain_negative[j] or config.gain[j] for j in range(2))
        self._gain_negative = (
            float(negative[0]) * float(config.polarity[0]),
            float(negative[1]) * float(config.polarity[1]),
        )
        self._bias = (float(config.null_bias[0]), float(config.null_bias[1]))
        self._deadband = (float(config.deadband[0]), float(config.deadband[1]))
        self._limit = (float(config.code_limit[0]), float(config.code_limit[1]))
        self._rate = (float(config.rate_limit[0]), float(config.rate_limit[1]))
        self._blend = float(config.deadband_blend)
        self._lag = (float(config.time_constants[0]), float(config.time_constants[1]))
        self.reset()

    @property
    def config(self) -> ValveOutputConfig:
        """The configuration."""
        return self._config

    def reset(self) -> None:
        """Valves at null: the rate limit starts again from code 0, the lag model from 0 N m."""
        self._last = [0.0, 0.0]
        self._before = (0.0, 0.0)
        self._codes = (0, 0)
        self._torque = (0.0, 0.0)
        self._clamped = (False, False)
        self._sample: OutputSample | None = None
        self._valve = [0.0, 0.0]

    def _code(self, joint: int, torque: float, dt: float) -> tuple[float, bool]:
        """D/A code (a whole float) for one joint's demand (N m), and whether it was clamped."""
        limit = self._limit[joint]
        deadband = self._deadband[joint]
        blend = self._blend
        if self._compensate:  # the goal that brings the modelled valve to the demand in dt
            torque = valve_lag_goal(self._valve[joint], torque, dt, self._lag[0], self._lag[1])
        demand = torque * (self._gain[joint] if torque >= 0.0 else self._gain_negative[joint])
        magnitude = abs(demand)
        if magnitude >= blend:  # demand != 0 here: np.sign is +-1
            wanted = magnitude + deadband if demand > 0.0 else -(magnitude + deadband)
        else:
            wanted = demand * (blend + deadband) / blend
        wanted += self._bias[joint]
        # np.clip(x, lo, hi) is min(max(x, lo), hi) with max(a, b) = a if a > b else b (b on a tie)
        saturated = wanted if wanted > -limit else -limit
        saturated = saturated if saturated < limit else limit
        step = self._rate[joint] * dt
        last = self._last[joint]
        low, high = last - step, last + step
        limited = saturated if saturated > low else low
        limited = limited if limited < high else high
        code = _rint(limited)
        code = code if code > -limit else -limit
        code = code if code < limit else limit
        self._last[joint] = code
        return code, saturated != wanted or limited != saturated

    def step_floats(self, torque: tuple[float, float], dt: float, again: bool = False) -> tuple[int, int]:
        """:meth:`step` for a demand the caller checked: finite floats (alpha, beta) (N m), ``dt`` > 0 (s).

        ``again``: a new answer to the measurement the last step answered replaces it (the rate limit
        starts from where that step started), so a re-sent answer moves the output once, not twice.
        """
        if again:
            self._last = [self._before[0], self._before[1]]
        else:
            self._before = (self._last[0], self._last[1])
        code_a, clamped_a = self._code(0, torque[0], dt)
        code_b, clamped_b = self._code(1, torque[1], dt)
        codes = (int(code_a), int(code_b))
        self._codes = codes
        self._torque = self._torque_floats(codes)
        self._clamped = (clamped_a, clamped_b)
        self._sample = None
        return codes

    def step(self, torque: npt.ArrayLike, dt: float) -> OutputSample:
        """Maps a torque demand (alpha, beta) (N m) held for ``dt`` seconds to D/A codes.

        Raises:
            ValueError: torque not finite shape (2,), or dt not a finite number > 0.
        """
        demand_torque = np.asarray(torque, dtype=np.float64)
        if demand_torque.shape != (2,) or not np.all(np.isfinite(demand_torque)):
            raise ValueError(f"torque must be finite, shape (2,), got {torque!r}")
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a finite number > 0 s, got {dt!r}")
        self.step_floats((float(demand_torque[0]), float(demand_torque[1])), float(dt))
        return self.last

    def _uncompensate(self, joint: int, code: float) -> float:
        deadband = self._deadband[joint]
        edge = self._blend + deadband
        magnitude = abs(code)
        if magnitude >= edge:  # code != 0 here: np.sign is +-1
            return magnitude - deadband if code > 0.0 else -(magnitude - deadband)
        return code * self._blend / edge

    def _joint_torque(self, joint: int, code: int) -> float:
        opening = self._uncompensate(joint, float(code) - self._bias[joint])
        torque = opening / self._gain[joint]
        return opening / self._gain_negative[joint] if torque < 0.0 else torque

    def _torque_floats(self, codes: tuple[int, int]) -> tuple[float, float]:
        return self._joint_torque(0, codes[0]), self._joint_torque(1, codes[1])

    def torque_of(self, codes: tuple[int, int]) -> FloatArray:
        """Torque (N m) that D/A ``codes`` command, the inverse of the map (without clamping), shape (2,)."""
        return np.array(self._torque_floats(codes), dtype=np.float64)

    def effort_floats(self, codes: tuple[int, int], dt: float) -> tuple[float, float]:
        """:meth:`effort` as Python floats (alpha, beta) (N m)."""
        target = self._torque_floats(codes)
        rise, fall = self._lag
        if rise == 0.0:
            return target
        valve = self._valve
        valve[0], mean_a = valve_lag_step(valve[0], target[0], dt, rise, fall)
        valve[1], mean_b = valve_lag_step(valve[1], target[1], dt, rise, fall)
        return mean_a, mean_b

    def effort(self, codes: tuple[int, int], dt: float) -> FloatArray:
        """Torque the valves gave over the last ``dt`` s (N m), shape (2,): ``codes`` through the lag model.

        Called once per board tick with the codes the board reports on its valves; without a lag model
        (``time_constants`` (0, 0)) it is :meth:`torque_of` ``codes``.
        """
        return np.array(self.effort_floats(codes, dt), dtype=np.float64)

    @property
    def last_codes(self) -> tuple[int, int]:
        """D/A codes of the last mapped command (alpha, beta), (0, 0) after reset."""
        return self._codes

    @property
    def last(self) -> OutputSample:
        """The last mapped command (codes 0 after reset)."""
        if self._sample is None:
            self._sample = OutputSample(
                self._codes,
                np.array(self._torque, dtype=np.float64),
                np.array(self._clamped, dtype=np.bool_),
            )
        return self._sample

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """``codes``, ``torque`` (N m) and ``clamped`` (0/1) of the last mapped command, shape (2,)."""
        return {
            "codes": np.array(self._codes, dtype=np.float64),
            "torque": np.array(self._torque, dtype=np.float64),
            "clamped": np.array(self._clamped, dtype=np.float64),
        }
