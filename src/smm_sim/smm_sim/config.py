"""Configuration of the simulator: the plant (:class:`PlantParameters`) and the run (:class:`SimNodeConfig`).

Both are mirrored as ``smm_sim_node``'s ROS parameters (``docs/LAUNCH.md``, smm_sim_node).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Final, Literal

from smm_schema.ranges import above, at_least, bounds, check_bounds, no_range

from smm_dynamics import SMMParameters
from smm_sim.plant import PlantConfig

__all__ = [
    "CLOCK_MODES",
    "MAX_COMMAND_TIMEOUT",
    "MAX_START_SUBSCRIBERS",
    "PlantParameters",
    "SimNodeConfig",
    "StartGate",
]

CLOCK_MODES: Final[tuple[str, ...]] = ("lockstep", "realtime")
MAX_COMMAND_TIMEOUT: Final[float] = 0.5
"""Largest ``command_timeout`` (s): beyond it a stale torque is held while the plant could reach its stop."""
_NS_PER_S: Final[int] = 1_000_000_000


@dataclass(frozen=True)
class PlantParameters:
    """ROS-parameter mirror of :class:`smm_sim.plant.PlantConfig` (fixed at start-up).

    Fields keep PlantConfig's names and units; two use a ROS-friendly encoding because ROS parameters have
    neither ``None`` nor (portably) infinity: ``torque_limit`` 0 means no saturation and
    ``valve_time_constants`` (0, 0) means no valve lag.

    Attributes:
        params: Nominal rigid-body parameters of the plant (the true plant scales their inertias).
        inertia_scale: Model error, factor on I11, I22, I44, I55 of the true plant (1.0 = none), > 0.
        noise_std: Standard deviation of the Gaussian position noise (alpha, beta) (rad), >= 0.
        encoder_counts_per_rev: Encoder resolution (counts per revolution), 0 = no quantisation.
        seed: Seed of the noise generator, >= 0; the same seed gives the same run.
        disturbance: External disturbance model, "none" or "eq46".
        joint_limits: Mechanical stops at +-limit (alpha, beta) (rad), in (0, pi/2).
        torque_limit: Saturation of the applied torque (alpha, beta) (N m), > 0; 0 = no saturation.
        torque_quantum: D/A resolution, torque of one code (alpha, beta) (N m), >= 0; 0 = none.
        valve_time_constants: Servo-valve lag (T_rise, T_fall) (s), > 0; (0, 0) = no lag.
        substeps: RK4 sub-steps per control period, >= 1.
        control_period: Control period (s), >= 1 ns.
        initial_position: Joint position at start (alpha, beta) (rad), inside the stops.
    """

    params: SMMParameters = field(default_factory=SMMParameters)
    inertia_scale: float = field(default=1.0, metadata=above(0.0))
    noise_std: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    encoder_counts_per_rev: int = field(default=0, metadata=at_least(0))
    seed: int = field(default=0, metadata=at_least(0))
    disturbance: Literal["none", "eq46"] = "none"
    joint_limits: tuple[float, float] = field(
        default=(1.3, 1.3), metadata=bounds(0.0, math.pi / 2, low_open=True, high_open=True)
    )
    torque_limit: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    torque_quantum: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    valve_time_constants: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    substeps: int = field(default=1, metadata=at_least(1))
    control_period: float = field(default=1e-3, metadata=at_least(1e-9))
    initial_position: tuple[float, float] = field(default=(0.0, 0.0), metadata=no_range())
    plant_config: PlantConfig = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("torque_limit", "valve_time_constants"):
            value = getattr(self, name)
            if not isinstance(value, tuple) or len(value) != 2:
                raise ValueError(f"{name} must be a tuple (alpha, beta) of 2 floats, got {value!r}")
        torque_limit = tuple(math.inf if limit == 0.0 else limit for limit in self.torque_limit)
        valve = None if self.valve_time_constants == (0.0, 0.0) else self.valve_time_constants
        config = PlantConfig(
            params=self.params,
            inertia_scale=self.inertia_scale,
            noise_std=self.noise_std,
            encoder_counts_per_rev=self.encoder_counts_per_rev,
            seed=self.seed,
            disturbance=self.disturbance,
            joint_limits=self.joint_limits,
            torque_limit=torque_limit,  # type: ignore[arg-type]
            torque_quantum=self.torque_quantum,
            valve_time_constants=valve,
            substeps=self.substeps,
            control_period=self.control_period,
        )
        position = self.initial_position
        if (
            not isinstance(position, tuple)
            or len(position) != 2
            or not all(isinstance(v, float) and math.isfinite(v) for v in position)
            or any(abs(v) > limit for v, limit in zip(position, self.joint_limits, strict=True))
        ):
            raise ValueError(
                f"initial_position must be 2 finite floats within joint_limits {self.joint_limits!r}, "
                f"got {position!r}"
            )
        object.__setattr__(self, "plant_config", config)


MAX_START_SUBSCRIBERS: Final[int] = 64


@dataclass(frozen=True)
class StartGate:
    """Lockstep: when the first measurement is published (parameters ``start.*``, fixed at start-up).

    Attributes:
        min_subscribers: Hold step 0 until ``joint_states`` has at least this many matched subscriptions
            and ``ground_truth`` and ``/clock`` at least one each, in [0, 64]; 0 = publish at once.
    """

    min_subscribers: int = field(default=0, metadata=bounds(0, MAX_START_SUBSCRIBERS))

    def __post_init__(self) -> None:
        check_bounds(self)


@dataclass(frozen=True)
class SimNodeConfig:
    """Behaviour of the simulator node (``clock_mode`` is fixed at start-up, the rest may change live).

    Attributes:
        clock_mode: "lockstep" (step when the answering command arrives; publishes /clock) or "realtime"
            (wall-clock timer at the control period).
        command_timeout: Realtime: a command older than this gives zero torque (s), in [0.001, 0.5]: longer
            would hold a stale torque for as long as the plant takes to fall onto its stop.
        republish_period: Lockstep: re-publish an unanswered measurement after this many wall seconds (s),
            > 0.
        max_steps: Stop after this many steps, >= 0; 0 = no limit.
        duration: Stop after this much plant time (s), >= 0; 0 = no limit.
        record_file: Write the run (.npz: stamps, true and measured position, velocity, applied and
            commanded torque) here at the end; "" = no record. The run is recorded only when this is
            set at start-up; a later change only moves where the record goes.
        stats_file: Write the run statistics (JSON: steps, drops, latency percentiles, deadline misses)
            here at the end; "" = none.
        stats_period: Realtime: log the latency statistics every this many wall seconds (s), >= 0;
            0 = only at the end.
        start: Lockstep: the start gate (:class:`StartGate`).
    """

    clock_mode: Literal["lockstep", "realtime"] = "realtime"
    command_timeout: float = field(default=0.05, metadata=bounds(1e-3, MAX_COMMAND_TIMEOUT))
    republish_period: float = field(default=0.1, metadata=above(0.0))
    max_steps: int = field(default=0, metadata=at_least(0))
    duration: float = field(default=0.0, metadata=at_least(0.0))
    record_file: str = ""
    stats_file: str = ""
    stats_period: float = field(default=5.0, metadata=at_least(0.0))
    start: StartGate = field(default_factory=StartGate)

    def __post_init__(self) -> None:
        if self.clock_mode not in CLOCK_MODES:
            raise ValueError(f"clock_mode must be one of {CLOCK_MODES}, got {self.clock_mode!r}")
        check_bounds(self)
        for name in ("command_timeout", "republish_period"):
            value = getattr(self, name)
            if not (isinstance(value, float) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0 s, got {value!r}")
        if isinstance(self.max_steps, bool) or not isinstance(self.max_steps, int) or self.max_steps < 0:
            raise ValueError(f"max_steps must be an int >= 0 (0 = no limit), got {self.max_steps!r}")
        for name in ("duration", "stats_period"):
            value = getattr(self, name)
            if not (isinstance(value, float) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0 s (0 = off), got {value!r}")

    def step_limit(self, period_ns: int) -> int | None:
        """Number of steps after which the run ends (None = no end), from max_steps and duration.

        Args:
            period_ns: Control period (ns).
        """
        limits = []
        if self.max_steps > 0:
            limits.append(self.max_steps)
        if self.duration > 0.0:
            limits.append(max(1, round(self.duration * _NS_PER_S / period_ns)))
        return min(limits) if limits else None
