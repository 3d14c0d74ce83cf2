"""Pure simulated SMM plant (SPEC sections 1-3): no ROS, no clock, deterministic for a seed.

:meth:`SimulatedPlant.step` takes a torque command through validation, saturation (and optional D/A
quantisation), the servo-valve lag, RK4 integration of eq. 2 and the mechanical stops;
:meth:`SimulatedPlant.measure` adds encoder noise and quantisation. Each stage, in order, and what the
applied torque reports: docs/DYNAMICS.md, "The simulated plant".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Final, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from smm_dynamics.valve import (
    PAPER_VALVE_RESPONSE_TIMES,
    valve_lag_step,
    valve_time_constants_from_response_times,
)
from smm_schema.ranges import above, at_least, bounds, check_bounds

from smm_dynamics import SMMParameters, rk4_step_floats

__all__ = [
    "DISTURBANCE_MODELS",
    "PAPER_VALVE_RESPONSE_TIMES",
    "DisturbanceModel",
    "GroundTruth",
    "Measurement",
    "PlantConfig",
    "SimulatedPlant",
    "disturbance_torque",
    "eq46_disturbance",
    "valve_time_constants_from_response_times",
]

FloatArray = NDArray[np.float64]
DisturbanceModel = Literal["none", "eq46"]

DISTURBANCE_MODELS: Final[tuple[str, ...]] = ("none", "eq46")
"""Names accepted by ``PlantConfig.disturbance``."""

_NS_PER_S: Final[int] = 1_000_000_000
# Standard normal variates drawn per refill of the noise block (two per sample).
_NOISE_BLOCK: Final[int] = 1024
_EQ46_ONSET_NS: Final[int] = 1_000_000_000
_EQ46_AMPLITUDE: Final[float] = 0.5
_EQ46_FREQUENCY: Final[float] = 7.0


def eq46_disturbance(t: float) -> tuple[float, float]:
    """External disturbance of eq. 46: 0 for t <= 1 s, then [-0.5 cos 7t, 0.5 cos 7t] (N m).

    Args:
        t: Time since the start of the run (s).

    Returns:
        (alpha, beta) disturbance torque (N m). It enters eq. 2 on the left-hand side, so it
        opposes a positive drive torque.
    """
    if t <= _EQ46_ONSET_NS / _NS_PER_S:
        return 0.0, 0.0
    value = _EQ46_AMPLITUDE * math.cos(_EQ46_FREQUENCY * t)
    return -value, value


def disturbance_torque(model: str, t: float) -> tuple[float, float]:
    """External disturbance torque of a named model at time ``t``.

    Args:
        model: One of :data:`DISTURBANCE_MODELS`.
        t: Time since the start of the run (s).

    Returns:
        (alpha, beta) disturbance torque (N m).
    """
    if model == "none":
        return 0.0, 0.0
    if model == "eq46":
        return eq46_disturbance(t)
    raise ValueError(f"disturbance must be one of {DISTURBANCE_MODELS}, got {model!r}")


@dataclass(frozen=True)
class PlantConfig:
    """Configuration of the simulated plant.

    Attributes:
        params: Nominal rigid-body parameters; the true plant uses them with the inertias scaled by
            ``inertia_scale``.
        inertia_scale: Model error: factor on I11, I22, I44, I55 of the true plant (1.0 = none;
            SPEC case2: 1.1), > 0.
        noise_std: Standard deviation of the Gaussian position noise (alpha, beta) (rad), >= 0.
        encoder_counts_per_rev: Encoder resolution (counts per revolution); 0 = no quantisation.
        seed: Seed of the noise generator (``numpy.random.default_rng``), >= 0.
        disturbance: External disturbance model, ``"none"`` or ``"eq46"``.
        joint_limits: Mechanical stops at +-limit (alpha, beta) (rad), in (0, pi/2) so the state
            never reaches the coordinate singularity at cos(beta) = 0.
        torque_limit: Saturation of the applied torque (alpha, beta) (N m), > 0; ``inf`` = off.
        torque_quantum: D/A resolution: torque of one D/A code (alpha, beta) (N m), >= 0; the saturated
            command is rounded to a whole number of codes. 0 = none (the default).
        valve_time_constants: (T_rise, T_fall) of the first-order valve lag (s), both > 0, or
            ``None`` (off). See :func:`valve_time_constants_from_response_times`.
        substeps: RK4 sub-steps per :meth:`SimulatedPlant.step` call, >= 1.
        control_period: Nominal control period (s), > 0; used by callers that step at a fixed rate
            (``period_ns``). Each ``step`` call still receives its own ``dt``.
    """

    params: SMMParameters = field(default_factory=SMMParameters)
    inertia_scale: float = field(default=1.0, metadata=above(0.0))
    noise_std: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    encoder_counts_per_rev: int = field(default=0, metadata=at_least(0))
    seed: int = field(default=0, metadata=at_least(0))
    disturbance: DisturbanceModel = "none"
    joint_limits: tuple[float, float] = field(
        default=(1.3, 1.3), metadata=bounds(0.0, math.pi / 2, low_open=True, high_open=True)
    )
    torque_limit: tuple[float, float] = field(default=(math.inf, math.inf), metadata=above(0.0, inf=True))
    torque_quantum: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    valve_time_constants: tuple[float, float] | None = field(default=None, metadata=above(0.0))
    substeps: int = field(default=1, metadata=at_least(1))
    control_period: float = field(default=1e-3, metadata=at_least(1e-9))

    def __post_init__(self) -> None:
        if not isinstance(self.params, SMMParameters):
            raise ValueError(f"params must be an SMMParameters, got {self.params!r}")
        check_bounds(self)
        if self.disturbance not in DISTURBANCE_MODELS:
            raise ValueError(f"disturbance must be one of {DISTURBANCE_MODELS}, got {self.disturbance!r}")

    @property
    def true_params(self) -> SMMParameters:
        """Parameters of the true plant: ``params`` with the inertias scaled by ``inertia_scale``."""
        if self.inertia_scale == 1.0:
            return self.params
        return self.params.with_inertia_scale(self.inertia_scale)

    @property
    def period_ns(self) -> int:
        """Control period in integer nanoseconds."""
        return round(self.control_period * _NS_PER_S)


@dataclass(frozen=True)
class Measurement:
    """One encoder sample, what the raw JointState carries.

    Attributes:
        stamp_ns: Sample time since reset (ns).
        position: Measured position (alpha, beta) (rad), noisy and quantised, shape (2,).
        applied_torque: Mean torque applied over the last control interval (N m), shape (2,);
            zeros before the first step.
    """

    stamp_ns: int
    position: FloatArray
    applied_torque: FloatArray


@dataclass(frozen=True)
class GroundTruth:
    """True state of the plant, for analysis only (the control chain must not use it).

    Attributes:
        stamp_ns: Time since reset (ns).
        position: True joint position q (rad), shape (2,).
        velocity: True joint velocity q' (rad/s), shape (2,).
        applied_torque: Mean torque applied over the last control interval (N m), shape (2,).
        disturbance_torque: External disturbance at ``stamp_ns`` (N m), shape (2,).
    """

    stamp_ns: int
    position: FloatArray
    velocity: FloatArray
    applied_torque: FloatArray
    disturbance_torque: FloatArray


def _validated_command(tau_command: ArrayLike) -> tuple[float, float]:
    if isinstance(tau_command, tuple) and len(tau_command) == 2:
        first, second = tau_command
        if type(first) is float and type(second) is float and math.isfinite(first) and math.isfinite(second):
            return first, second  # fast path for the offline loop, which passes a pair of floats
    try:
        command = np.asarray(tau_command, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"tau_command must be numeric, shape (2,), got {tau_command!r}") from error
    if command.shape != (2,):
        raise ValueError(f"tau_command must have shape (2,), got shape {command.shape}")
    first, second = float(command[0]), float(command[1])
    if not (math.isfinite(first) and math.isfinite(second)):
        raise ValueError(f"tau_command must be finite, got {command.tolist()!r}")
    return first, second


_NO_DT: Final[object] = object()
"""The cached dt before the first step: no argument is this object, so the first dt is always validated."""


def _validated_dt_ns(dt: float) -> int:
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not math.isfinite(dt):
        raise ValueError(f"dt must be a finite number of seconds, got {dt!r}")
    dt_ns = round(dt * _NS_PER_S)
    if dt_ns <= 0:
        raise ValueError(f"dt must be >= 1 ns, got {dt!r}")
    return dt_ns


class SimulatedPlant:
    """The 2-DOF SMM with sensing and actuation models; see the module docstring for the order.

    Args:
        config: Plant configuration.
    """

    def __init__(self, config: PlantConfig) -> None:
        self._config = config
        self._params = config.true_params
        self._limits = config.joint_limits
        self._saturation = config.torque_limit
        self._quantum = (
            2.0 * math.pi / config.encoder_counts_per_rev if config.encoder_counts_per_rev else 0.0
        )
        self._rng = np.random.default_rng(config.seed)
        self._noise_std = config.noise_std if config.noise_std[0] > 0.0 or config.noise_std[1] > 0.0 else None
        self._normals: list[float] = []
        self._normal_index = 0
        self._unlimited = math.isinf(config.torque_limit[0]) and math.isinf(config.torque_limit[1])
        self._quantised = config.torque_quantum != (0.0, 0.0)
        # dt of the last step and its validated length in ns (the loops pass the same dt every step).
        self._last_dt: object = _NO_DT
        self._last_dt_ns = 0
        # (alpha, beta, alpha', beta') (rad, rad/s), plain floats for the single-sample RK4.
        self._state = (0.0, 0.0, 0.0, 0.0)
        self._t_ns = 0
        self._valve = [0.0, 0.0]
        self._command = (0.0, 0.0)
        self._applied = (0.0, 0.0)
        self._noise = (0.0, 0.0)
        self._measured = (0.0, 0.0)
        self.reset()

    @property
    def config(self) -> PlantConfig:
        """The configuration this plant was built with."""
        return self._config

    def reset(self, position: ArrayLike | None = None) -> None:
        """Restarts at rest at t = 0 with a freshly seeded noise generator.

        Args:
            position: Initial joint position (rad), shape (2,), inside the stops; default q = 0.
        """
        q0 = np.zeros(2) if position is None else np.array(position, dtype=np.float64)
        if q0.shape != (2,) or not np.all(np.isfinite(q0)):
            raise ValueError(f"position must be finite, shape (2,), got {position!r}")
        if np.any(np.abs(q0) > np.asarray(self._limits)):
            raise ValueError(f"position must lie within joint_limits {self._limits}, got {q0.tolist()!r}")
        self._rng = np.random.default_rng(self._config.seed)
        self._normals = []
        self._normal_index = 0
        self._state = (float(q0[0]), float(q0[1]), 0.0, 0.0)
        self._t_ns = 0
        self._valve = [0.0, 0.0]
        self._command = (0.0, 0.0)
        self._applied = (0.0, 0.0)
        self._sample_sensor()

    @property
    def time_ns(self) -> int:
        """Time since reset (ns)."""
        return self._t_ns

    def measure(self) -> Measurement:
        """The encoder sample at the current time (the same sample however often it is called).

        Returns:
            Noisy, quantised position and the torque applied over the last interval.
        """
        return Measurement(
            stamp_ns=self._t_ns,
            position=np.array(self._measured),
            applied_torque=np.array(self._applied),
        )

    def measure_floats(self) -> tuple[float, float, float, float]:
        """:meth:`measure` without the arrays, for loops that step the plant one sample at a time.

        Returns:
            (measured alpha, measured beta) (rad) and (applied alpha, applied beta) (N m), the values of
            ``measure().position`` and ``measure().applied_torque``.
        """
        return (*self._measured, *self._applied)

    @property
    def state_floats(self) -> tuple[float, float, float, float]:
        """True (alpha, beta, alpha', beta') (rad, rad/s): ``ground_truth`` position and velocity."""
        return self._state

    @property
    def ground_truth(self) -> GroundTruth:
        """True q, q', applied torque and disturbance at the current time."""
        alpha, beta, alpha_dot, beta_dot = self._state
        return GroundTruth(
            stamp_ns=self._t_ns,
            position=np.array((alpha, beta)),
            velocity=np.array((alpha_dot, beta_dot)),
            applied_torque=np.array(self._applied),
            disturbance_torque=np.array(disturbance_torque(self._config.disturbance, self._t_ns / _NS_PER_S)),
        )

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Actuator and sensor internals, shape (2,) each (copies).

        Keys: ``commanded_torque`` (last command, N m), ``saturated_torque`` (after the limit, N m),
        ``valve_torque`` (lag output at the current time, N m), ``applied_torque`` (mean over the last
        interval, N m), ``disturbance_torque`` (N m), ``measurement_noise`` (rad).
        """
        saturated = tuple(self._saturate(self._command))
        return {
            "commanded_torque": np.array(self._command),
            "saturated_torque": np.array(saturated),
            "valve_torque": np.array(self._valve),
            "applied_torque": np.array(self._applied),
            "disturbance_torque": np.array(
                disturbance_torque(self._config.disturbance, self._t_ns / _NS_PER_S)
            ),
            "measurement_noise": np.array(self._noise),
        }

    def step(self, tau_command: ArrayLike, dt: float) -> None:
        """Applies a torque command over [t, t + dt] and advances the plant.

        Args:
            tau_command: Commanded torque (alpha, beta) (N m), shape (2,), finite.
            dt: Interval (s), rounded to whole nanoseconds, >= 1 ns.

        Raises:
            ValueError: The command is not finite or not shape (2,), or dt is invalid. The plant state
                is left untouched.
        """
        command = _validated_command(tau_command)
        if dt is self._last_dt:
            dt_ns = self._last_dt_ns
        else:
            dt_ns = _validated_dt_ns(dt)
            self._last_dt, self._last_dt_ns = dt, dt_ns
        config = self._config
        saturated = command if self._unlimited else self._saturate(command)
        if self._quantised:
            saturated = self._quantise(saturated)
        substeps = config.substeps
        h = dt_ns / _NS_PER_S / substeps
        t0 = self._t_ns / _NS_PER_S
        state = self._state
        applied_sum = [0.0, 0.0]
        lagged = config.valve_time_constants is not None
        if not lagged:
            self._valve = [saturated[0], saturated[1]]
        for index in range(substeps):
            torque = self._valve_substep(saturated, h) if lagged else saturated
            applied_sum[0] += torque[0]
            applied_sum[1] += torque[1]
            t_mid = t0 + (index + 0.5) * h
            dist = disturbance_torque(config.disturbance, t_mid)
            state = self._apply_stops(rk4_step_floats(state, torque, h, self._params, disturbance=dist))
        self._state = state
        self._command = command
        self._applied = (applied_sum[0] / substeps, applied_sum[1] / substeps)
        self._t_ns += dt_ns
        self._sample_sensor()

    def _saturate(self, command: tuple[float, float]) -> tuple[float, float]:
        limit_a, limit_b = self._saturation
        return (min(max(command[0], -limit_a), limit_a), min(max(command[1], -limit_b), limit_b))

    def _quantise(self, torque: tuple[float, float]) -> tuple[float, float]:
        quantised = []
        for value, quantum in zip(torque, self._config.torque_quantum, strict=True):
            quantised.append(round(value / quantum) * quantum if quantum > 0.0 else value)
        return quantised[0], quantised[1]

    def _valve_substep(self, target: tuple[float, float], h: float) -> tuple[float, float]:
        """Advances the valve lag by h towards ``target``; returns the mean torque over the sub-step."""
        constants = self._config.valve_time_constants
        assert constants is not None  # step() bypasses the lag when there is none
        rise, fall = constants
        alpha, mean_alpha = valve_lag_step(self._valve[0], target[0], h, rise, fall)
        beta, mean_beta = valve_lag_step(self._valve[1], target[1], h, rise, fall)
        self._valve = [alpha, beta]
        return mean_alpha, mean_beta

    def _apply_stops(self, state: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
        alpha, beta, alpha_dot, beta_dot = state
        limit_alpha, limit_beta = self._limits
        if alpha > limit_alpha:
            alpha, alpha_dot = limit_alpha, min(alpha_dot, 0.0)
        elif alpha < -limit_alpha:
            alpha, alpha_dot = -limit_alpha, max(alpha_dot, 0.0)
        if beta > limit_beta:
            beta, beta_dot = limit_beta, min(beta_dot, 0.0)
        elif beta < -limit_beta:
            beta, beta_dot = -limit_beta, max(beta_dot, 0.0)
        return alpha, beta, alpha_dot, beta_dot

    def _sample_sensor(self) -> None:
        std = self._noise_std
        if std is not None:
            index = self._normal_index
            if index == len(self._normals):
                self._normals = self._rng.standard_normal(_NOISE_BLOCK).tolist()
                index = 0
            self._normal_index = index + 2
            self._noise = (self._normals[index] * std[0], self._normals[index + 1] * std[1])
        else:
            self._noise = (0.0, 0.0)
        measured_alpha = self._state[0] + self._noise[0]
        measured_beta = self._state[1] + self._noise[1]
        quantum = self._quantum
        if quantum > 0.0:
            # np.round on floats: round() rounds half to even, copysign keeps the sign of a zero count.
            counts_alpha = measured_alpha / quantum
            counts_beta = measured_beta / quantum
            measured_alpha = math.copysign(round(counts_alpha), counts_alpha) * quantum
            measured_beta = math.copysign(round(counts_beta), counts_beta) * quantum
        self._measured = (measured_alpha, measured_beta)
