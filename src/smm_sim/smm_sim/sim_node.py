"""``smm_sim_node``: the simulated plant (:class:`smm_sim.plant.SimulatedPlant`) as a ROS 2 node.

Topics (relative, so under the graph's namespace ``/smm``; see ``docs/INTERFACES.md``):

* publishes ``joint_states`` (raw measurement: ``position`` rad, ``effort`` = torque applied over the last
  interval, N m; ``header.stamp`` = sample time), ``ground_truth`` (true position, velocity, effort;
  analysis only) and, in lockstep, ``/clock``;
* subscribes ``torque_command`` (``Float64MultiArray`` [tau_alpha, tau_beta] N m, stamped with the
  measurement it answers).

Stamps are the plant's time since start (``k * control_period`` exactly, integer ns) in both clock modes,
so a record or a bag of either mode lines up with the offline simulator sample by sample.

Clock modes (parameter ``clock_mode``, fixed at start-up):

* ``lockstep``: the node publishes ``/clock`` and the measurement of step k, and advances one step only when
  the torque command stamped with that measurement's stamp arrives. A command for an older stamp is a late
  re-transmission and is ignored quietly; one for a stamp never published is dropped with a warning.
  Messages published before the subscribers matched are lost in DDS, so the current measurement is
  re-published every ``republish_period`` wall seconds until it is answered (the controller nodes answer a
  repeated stamp by re-publishing their last answer without stepping). A run is therefore deterministic for
  a seed and goes as fast as the graph allows. With ``start.min_subscribers`` > 0 the measurement of step
  0 is held until ``joint_states`` has that many matched subscriptions and ``ground_truth`` and ``/clock``
  one each (a recorder: nothing else reads those), so that a recorder started with the graph sees step 0.
* ``realtime``: a steady-clock timer steps the plant every ``control_period`` with the latest valid command;
  a command older than ``command_timeout`` gives zero torque (throttled warning). The node measures the
  measurement-to-command latency (receive time of the first answer minus publish time of the answered
  measurement) and the deadline misses (a tick at which the answer to the previous measurement had not
  arrived) and logs them every ``stats_period`` seconds.

End of a run: after ``max_steps`` steps or ``duration`` seconds of plant time (whichever comes first; 0 means
no limit) the node writes ``record_file`` / ``stats_file`` (when set), logs a summary and completes
:attr:`SimNode.done`; :func:`main` then exits 0. That exit is how ``smm-launch`` (and the launch file's
``OnProcessExit`` handler) know the run is complete.

Bad commands (NaN/Inf, wrong length, bad layout, bad or unknown stamp) are dropped with a throttled warning
and counted; they never reach the integrator.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Literal, Unpack

import numpy as np
import numpy.typing as npt
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType  # type: ignore[attr-defined]
from rclpy.context import Context
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.task import Future
from rclpy.timer import Timer
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from smm_msgs_py.conversions import JointSample, clock_msg, msg_to_torque, sample_to_joint_state
from smm_msgs_py.errors import InterfaceError
from smm_msgs_py.qos import qos_for_topic, subscription_qos_for_topic
from smm_node_runtime.parameters import ConfigParameters, bounds, check_bounds
from std_msgs.msg import Float64MultiArray

from smm_dynamics import SMMParameters
from smm_msgs_py import topics
from smm_node_runtime import (
    WARN_THROTTLE_S,
    CountWindows,
    DiagnosticsPublisher,
    Health,
    Level,
    NodeOptions,
    SmmNode,
    run_node,
    wait_for_delivery,
    worst,
)
from smm_sim.plant import GroundTruth, Measurement, PlantConfig, SimulatedPlant

__all__ = [
    "CLOCK_MODES",
    "NODE_NAME",
    "LatencyStats",
    "PlantDivergedError",
    "PlantParameters",
    "SimNode",
    "SimNodeConfig",
    "SimParameterError",
    "StartGate",
    "main",
    "statistics_summary",
]

NODE_NAME: Final[str] = "smm_sim_node"
CLOCK_MODES: Final[tuple[str, ...]] = ("lockstep", "realtime")
_NS_PER_S: Final[int] = 1_000_000_000
_STARTUP_ONLY: Final[frozenset[str]] = frozenset({"clock_mode", "start.min_subscribers"})
_GATE_POLL_S: Final[float] = 0.01
_GATE_LOG_S: Final[float] = 2.0
_DELIVERY_TIMEOUT_S: Final[float] = 5.0
"""Longest wait at the end of a run for the subscribers to acknowledge the last messages (s): more than
Fast DDS's 3 s heartbeat period, after which a reliable writer resends what a reader lacks."""
_PUBLISHED_STAMPS_KEPT: Final[int] = 1000
MAX_COMMAND_TIMEOUT: Final[float] = 0.5
"""Largest ``command_timeout`` (s): beyond it a stale torque is held while the plant could reach its stop."""
DEADLINE_MISS_WARN_FRACTION: Final[float] = 0.1
"""Real time: WARN when more than this fraction of a period's ticks found the previous one unanswered."""
"""Realtime: publish times of this many recent measurements are kept to match answers (1 s at 1 kHz)."""

FloatArray = npt.NDArray[np.float64]


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
    inertia_scale: float = 1.0
    noise_std: tuple[float, float] = (0.0, 0.0)
    encoder_counts_per_rev: int = 0
    seed: int = 0
    disturbance: Literal["none", "eq46"] = "none"
    joint_limits: tuple[float, float] = (1.3, 1.3)
    torque_limit: tuple[float, float] = (0.0, 0.0)
    torque_quantum: tuple[float, float] = (0.0, 0.0)
    valve_time_constants: tuple[float, float] = (0.0, 0.0)
    substeps: int = 1
    control_period: float = 1e-3
    initial_position: tuple[float, float] = (0.0, 0.0)
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
    republish_period: float = 0.1
    max_steps: int = 0
    duration: float = 0.0
    record_file: str = ""
    stats_file: str = ""
    stats_period: float = 5.0
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


class SimParameterError(ValueError):
    """A parameter of smm_sim_node has an invalid value (the message names the parameter and the value)."""


class PlantDivergedError(RuntimeError):
    """The simulated plant's state became non-finite (the closed loop is unstable); the run is over."""


class LatencyStats:
    """Measurement-to-command latencies (ns), kept whole for exact percentiles (8 bytes per sample)."""

    def __init__(self) -> None:
        self._samples: list[int] = []

    def add(self, latency_ns: int) -> None:
        """Record one latency (ns)."""
        self._samples.append(latency_ns)

    @property
    def count(self) -> int:
        """Number of latencies recorded."""
        return len(self._samples)

    def percentile_us(self, percent: float) -> float:
        """The ``percent`` percentile (0-100) in microseconds; NaN when empty."""
        if not self._samples:
            return math.nan
        return float(np.percentile(np.asarray(self._samples, dtype=np.float64), percent)) / 1e3

    def summary(self) -> dict[str, float]:
        """count, p50, p90, p99 and max (us)."""
        return {
            "count": float(self.count),
            "p50_us": self.percentile_us(50.0),
            "p90_us": self.percentile_us(90.0),
            "p99_us": self.percentile_us(99.0),
            "max_us": self.percentile_us(100.0),
        }


def statistics_summary(stats: Mapping[str, Any]) -> str:
    """One log line of :meth:`SimNode.statistics`: the figures that mean something in its clock mode.

    Lockstep: steps and stepping rate (latency and deadlines do not exist: the plant waits for every
    answer). Real time: latency percentiles, deadline misses, late and zero-torque ticks. Both: the
    commands dropped.
    """
    dropped = (
        f"dropped {stats['dropped_invalid']} invalid, {stats['dropped_unknown_stamp']} unknown-stamp commands"
    )
    if stats["clock_mode"] == "lockstep":
        rate = stats["steps_per_wall_second"]
        rate_text = f" at {rate:.0f} steps/s" if math.isfinite(rate) else ""
        return f"{stats['steps']} steps{rate_text} (lockstep); republished {stats['republished']}; {dropped}"
    latency = stats["latency"]
    answers = int(latency["count"])
    latency_text = (
        f"latency p50 {latency['p50_us']:.0f} us, p99 {latency['p99_us']:.0f} us ({answers} answers)"
        if answers
        else "no command answered a measurement"
    )
    return (
        f"{stats['steps']} steps (real time); {latency_text}; deadline misses {stats['deadline_misses']}, "
        f"late ticks {stats['late_ticks']}, zero-torque ticks {stats['stale_ticks']}; {dropped}"
    )


class _Recorder:
    """Per-step record of the run (lists of floats, converted to arrays once at the end)."""

    def __init__(self) -> None:
        self.stamp_ns: list[int] = []
        self.position: list[tuple[float, float]] = []
        self.velocity: list[tuple[float, float]] = []
        self.applied_torque: list[tuple[float, float]] = []
        self.measured_position: list[tuple[float, float]] = []
        self.command_stamp_ns: list[int] = []
        self.command: list[tuple[float, float]] = []

    def sample(self, truth: GroundTruth, measured: Measurement) -> None:
        self.stamp_ns.append(truth.stamp_ns)
        self.position.append((float(truth.position[0]), float(truth.position[1])))
        self.velocity.append((float(truth.velocity[0]), float(truth.velocity[1])))
        self.applied_torque.append((float(truth.applied_torque[0]), float(truth.applied_torque[1])))
        self.measured_position.append((float(measured.position[0]), float(measured.position[1])))

    def command_applied(self, stamp_ns: int, command: tuple[float, float]) -> None:
        self.command_stamp_ns.append(stamp_ns)
        self.command.append(command)

    def save(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(
            path,
            stamp_ns=np.asarray(self.stamp_ns, dtype=np.int64),
            position=np.asarray(self.position, dtype=np.float64).reshape(-1, 2),
            velocity=np.asarray(self.velocity, dtype=np.float64).reshape(-1, 2),
            applied_torque=np.asarray(self.applied_torque, dtype=np.float64).reshape(-1, 2),
            measured_position=np.asarray(self.measured_position, dtype=np.float64).reshape(-1, 2),
            command_stamp_ns=np.asarray(self.command_stamp_ns, dtype=np.int64),
            command=np.asarray(self.command, dtype=np.float64).reshape(-1, 2),
        )


class SimNode(SmmNode):
    """The simulated SMM plant node (see the module docstring).

    Args:
        shutdown_when_done: Shut the context down when the run is complete, which ends the spin of
            :func:`smm_node_runtime.run_node` (the console script); a launcher that composes nodes waits
            for :attr:`done` instead.
        **options: The node options every SMM node takes (:class:`~smm_node_runtime.NodeOptions`).

    Raises:
        SimParameterError: A parameter value is invalid (the message names the parameter and the value).
    """

    NODE_NAME = NODE_NAME

    def __init__(self, *, shutdown_when_done: bool = False, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        try:
            self._plant_parameters = ConfigParameters(self, "", PlantParameters(), read_only=True)
            self._node_parameters = ConfigParameters(
                self, "", SimNodeConfig(), on_change=self._on_config_change
            )
        except ValueError as error:
            self.destroy_node()
            raise SimParameterError(str(error)) from error
        self._shutdown_when_done = shutdown_when_done
        self._log = self.get_logger()  # type: ignore[no-untyped-call]
        # Registered after the declarations, which run the set-parameters callbacks too.
        self.add_on_set_parameters_callback(self._refuse_startup_only)
        plant_parameters = self._plant_parameters.config
        self._clock_mode = self._node_parameters.config.clock_mode
        self._plant = SimulatedPlant(plant_parameters.plant_config)
        self._plant.reset(np.asarray(plant_parameters.initial_position))
        self._period_ns = plant_parameters.plant_config.period_ns
        self._dt = self._period_ns / _NS_PER_S

        self.done: Future = Future()  # type: ignore[no-untyped-call]
        """Completed (result: number of steps) when the run reached ``max_steps`` / ``duration``."""
        self.steps = 0
        self.dropped_invalid = 0
        self.dropped_unknown_stamp = 0
        self.ignored_late = 0
        self.republished = 0
        self.published: dict[str, int] = {}
        """Messages published per topic (fully qualified name), re-publications included."""
        self.stale_ticks = 0
        self.deadline_misses = 0
        self.late_ticks = 0
        self.latency = LatencyStats()
        self._first_step_ns: int | None = None
        self._last_step_ns = 0
        self._measurement = self._plant.measure()
        self._truth = self._plant.ground_truth
        # Kept only when asked for at start-up: a record grows by about 0.5 kB per step.
        self._recorder = _Recorder() if self._node_parameters.config.record_file else None
        if self._recorder is not None:
            self._recorder.sample(self._truth, self._measurement)
        self._finished = False
        self.command_timeouts = 0
        """Real-time ticks that applied zero torque because the command in force had timed out."""
        self.ticks_on_stop = 0
        """Steps that ended with a joint on its mechanical stop."""
        self.last_error = ""
        self._joint_limits = plant_parameters.joint_limits
        self._windows = CountWindows({})
        self.diagnostics = DiagnosticsPublisher(self, self.health, on_period=self._end_period)

        self._joint_states_pub = self.create_publisher(
            JointState, topics.JOINT_STATES, qos_for_topic(topics.JOINT_STATES)
        )
        self._ground_truth_pub = self.create_publisher(
            JointState, topics.GROUND_TRUTH, qos_for_topic(topics.GROUND_TRUTH)
        )
        self._clock_pub = (
            self.create_publisher(ClockMsg, topics.CLOCK, qos_for_topic(topics.CLOCK))
            if self._clock_mode == "lockstep"
            else None
        )
        self.create_subscription(
            Float64MultiArray,
            topics.TORQUE_COMMAND,
            self._on_command,
            subscription_qos_for_topic(topics.TORQUE_COMMAND),
        )
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._stats_timer: Timer | None = None
        # Realtime state: the latest valid command and when it arrived (monotonic ns).
        self._command: tuple[float, float] = (0.0, 0.0)
        self._command_stamp_ns = -1
        self._command_received_ns: int | None = None
        self._published_at: OrderedDict[int, int] = OrderedDict()
        self._answered_previous = True
        self._next_tick_ns = 0
        # Lockstep state: when the current measurement was last published (monotonic ns).
        self._last_publish_ns = 0
        self._step_limit = self._node_parameters.config.step_limit(self._period_ns)

        self._gate: Timer | None = None
        if self._clock_mode == "lockstep":
            self._timer = self.create_timer(
                self._node_parameters.config.republish_period, self._on_republish_timer, clock=self._steady
            )
            if self._node_parameters.config.start.min_subscribers > 0:
                self._gate = self.create_timer(_GATE_POLL_S, self._on_gate_timer, clock=self._steady)
            else:
                self._publish_measurement()
        else:
            self._timer = self.create_timer(self._dt, self._on_realtime_tick, clock=self._steady)
            self._next_tick_ns = time.monotonic_ns() + self._period_ns
            self._restart_stats_timer(self._node_parameters.config.stats_period)
            self._publish_measurement()
        self._log.info(
            f"{self._clock_mode} simulation, period {self._dt * 1e3:g} ms, "
            f"{'no step limit' if self._step_limit is None else f'{self._step_limit} steps'}, "
            f"seed {plant_parameters.seed}, disturbance {plant_parameters.disturbance}, "
            f"inertia scale {plant_parameters.inertia_scale:g}, "
            f"noise std {list(plant_parameters.noise_std)} rad"
        )

    # ------------------------------------------------------------------------------------- properties

    @property
    def clock_mode(self) -> str:
        """The clock mode, "lockstep" or "realtime" (fixed at start-up)."""
        return self._clock_mode

    @property
    def plant(self) -> SimulatedPlant:
        """The simulated plant (read it only from the executor's thread)."""
        return self._plant

    @property
    def config(self) -> SimNodeConfig:
        """The current node configuration."""
        return self._node_parameters.config

    @property
    def plant_parameters(self) -> PlantParameters:
        """The plant parameters (fixed at start-up)."""
        return self._plant_parameters.config

    @property
    def current_stamp_ns(self) -> int:
        """Stamp of the latest published measurement (ns since start)."""
        return self._plant.time_ns

    @property
    def finished(self) -> bool:
        """True once the run reached its step limit."""
        return self._finished

    def statistics(self) -> dict[str, Any]:
        """Counters, latency figures and stepping rate of the run so far (JSON-serialisable).

        ``steps_per_wall_second`` counts from the first step to the last, so start-up and discovery are
        not in it.
        """
        first = self._first_step_ns
        stepping_s = 0.0 if first is None else (self._last_step_ns - first) / _NS_PER_S
        return {
            "clock_mode": self._clock_mode,
            "steps": self.steps,
            "control_period_s": self._dt,
            "dropped_invalid": self.dropped_invalid,
            "dropped_unknown_stamp": self.dropped_unknown_stamp,
            "ignored_late": self.ignored_late,
            "republished": self.republished,
            "published": dict(sorted(self.published.items())),
            "stale_ticks": self.stale_ticks,
            "deadline_misses": self.deadline_misses,
            "late_ticks": self.late_ticks,
            "latency": self.latency.summary(),
            "stepping_wall_s": stepping_s,
            "steps_per_wall_second": (self.steps - 1) / stepping_s if stepping_s > 0.0 else math.nan,
        }

    # ------------------------------------------------------------------------------------- parameters

    def _refuse_startup_only(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name in _STARTUP_ONLY and parameter.value != _value_at(self.config, parameter.name):
                return SetParametersResult(
                    successful=False,
                    reason=f"{parameter.name} is fixed at start-up; restart the node to change it",
                )
        return SetParametersResult(successful=True)

    def _on_config_change(self, config: SimNodeConfig) -> None:
        self._step_limit = config.step_limit(self._period_ns)
        if self._clock_mode == "lockstep":
            self._timer.destroy()  # type: ignore[no-untyped-call]
            self._timer = self.create_timer(
                config.republish_period, self._on_republish_timer, clock=self._steady
            )
        else:
            self._restart_stats_timer(config.stats_period)
        if self._step_limit is not None and self.steps >= self._step_limit:
            self._finish()

    def _restart_stats_timer(self, period: float) -> None:
        if self._stats_timer is not None:
            self._stats_timer.destroy()  # type: ignore[no-untyped-call]
            self._stats_timer = None
        if period > 0.0:
            self._stats_timer = self.create_timer(period, self._log_statistics, clock=self._steady)

    # ---------------------------------------------------------------------------------------- commands

    def _warn(self, message: str) -> None:
        self._log.warning(message, throttle_duration_sec=WARN_THROTTLE_S)

    def _on_command(self, msg: Float64MultiArray) -> None:
        received_ns = time.monotonic_ns()
        if self._finished:
            return
        try:
            command = msg_to_torque(msg)
        except InterfaceError as error:
            self.dropped_invalid += 1
            self._warn(
                f"dropped torque command ({type(error).__name__}: {error}); "
                f"{self.dropped_invalid} invalid commands so far"
            )
            return
        values = (float(command.values[0]), float(command.values[1]))
        stamp_ns = command.stamp_ns
        if self._clock_mode == "lockstep":
            self._lockstep_command(stamp_ns, values)
        else:
            self._realtime_command(stamp_ns, values, received_ns)

    def _drop_unknown_stamp(self, stamp_ns: int) -> None:
        self.dropped_unknown_stamp += 1
        self._warn(
            f"dropped torque command for stamp {stamp_ns} ns: no measurement with that stamp was published "
            f"(current {self._plant.time_ns} ns); {self.dropped_unknown_stamp} such commands so far"
        )

    def _lockstep_command(self, stamp_ns: int, values: tuple[float, float]) -> None:
        current = self._plant.time_ns
        if stamp_ns < current:
            # A re-transmitted answer to a measurement that was already answered: expected, not an error.
            self.ignored_late += 1
            return
        if stamp_ns > current:
            self._drop_unknown_stamp(stamp_ns)
            return
        self._step(values, stamp_ns)
        if not self._finished:
            self._publish_measurement()

    def _realtime_command(self, stamp_ns: int, values: tuple[float, float], received_ns: int) -> None:
        published_ns = self._published_at.get(stamp_ns)
        if published_ns is None:
            if stamp_ns <= self._command_stamp_ns or (
                self._published_at and stamp_ns < next(iter(self._published_at))
            ):
                self.ignored_late += 1
            else:
                self._drop_unknown_stamp(stamp_ns)
            return
        if stamp_ns <= self._command_stamp_ns:
            # Out of order or repeated: a newer answer is already in force.
            self.ignored_late += 1
            return
        self._command = values
        self._command_stamp_ns = stamp_ns
        self._command_received_ns = received_ns
        self.latency.add(received_ns - published_ns)
        if stamp_ns == self._plant.time_ns:
            self._answered_previous = True

    # ------------------------------------------------------------------------------------------ stepping

    def _step(self, command: tuple[float, float], command_stamp_ns: int) -> None:
        self._plant.step(command, self._dt)
        self.steps += 1
        self._last_step_ns = time.monotonic_ns()
        if self._first_step_ns is None:
            self._first_step_ns = self._last_step_ns
        self._measurement = self._plant.measure()
        self._truth = self._plant.ground_truth
        if self._recorder is not None:
            self._recorder.command_applied(command_stamp_ns, command)
            self._recorder.sample(self._truth, self._measurement)
        position = self._truth.position
        if abs(position[0]) >= self._joint_limits[0] or abs(position[1]) >= self._joint_limits[1]:
            self.ticks_on_stop += 1
        state = (*self._truth.position.tolist(), *self._truth.velocity.tolist())
        if not all(map(math.isfinite, state)):
            self._diverged(command)
        if self._step_limit is not None and self.steps >= self._step_limit:
            self._finish()

    def _diverged(self, command: tuple[float, float]) -> None:
        """The integration blew up (an unstable loop drove the state to Inf/NaN): end the run as failed.

        :attr:`done` completes with a :class:`PlantDivergedError`; the console script exits 1.
        """
        message = (
            f"plant state became non-finite at t = {self._plant.time_ns / _NS_PER_S:g} s after torque "
            f"{list(command)} N m (unstable closed loop?); stopping the simulation"
        )
        self._log.error(message)
        self._finished = True
        self._timer.cancel()  # type: ignore[no-untyped-call]
        self.write_outputs()
        self.done.set_exception(PlantDivergedError(message))  # type: ignore[no-untyped-call]
        if self._shutdown_when_done:
            self.context.try_shutdown()

    def _publish_measurement(self) -> None:
        measurement = self._measurement
        truth = self._truth
        stamp_ns = measurement.stamp_ns
        message = sample_to_joint_state(
            JointSample(stamp_ns, measurement.position, None, measurement.applied_torque)
        )
        # The measurement goes first: the controller-side nodes (other processes) start on it while this node
        # publishes the clock and the ground truth. Nothing in the loop reads /clock (stamps carry the time).
        now_ns = time.monotonic_ns()
        self._publish(self._joint_states_pub, message)
        self._last_publish_ns = now_ns
        # /clock only matters to nodes running on sim time (they subscribe to it); unobserved, it is skipped.
        if self._clock_pub is not None and self._clock_pub.get_subscription_count() > 0:
            self._publish(self._clock_pub, clock_msg(stamp_ns))
        # Ground truth is for analysis only: built and sent only while something (a recorder) listens.
        if self._ground_truth_pub.get_subscription_count() > 0:
            sample = JointSample(stamp_ns, truth.position, truth.velocity, truth.applied_torque)
            self._publish(self._ground_truth_pub, sample_to_joint_state(sample))
        if self._clock_mode == "realtime":
            self._published_at[stamp_ns] = now_ns
            while len(self._published_at) > _PUBLISHED_STAMPS_KEPT:
                self._published_at.popitem(last=False)

    def _publish(self, publisher: Publisher, message: object) -> None:
        publisher.publish(message)
        self.published[publisher.topic_name] = self.published.get(publisher.topic_name, 0) + 1

    def _gate_shortfall(self) -> list[str]:
        """The publishers still short of their start subscribers, as ``topic n/needed``; [] = open."""
        wanted = self.config.start.min_subscribers
        needed = [(self._joint_states_pub, wanted), (self._ground_truth_pub, 1)]
        if self._clock_pub is not None:
            needed.append((self._clock_pub, 1))
        return [
            f"{publisher.topic_name} {publisher.get_subscription_count()}/{count}"
            for publisher, count in needed
            if publisher.get_subscription_count() < count
        ]

    def _on_gate_timer(self) -> None:
        assert self._gate is not None
        short = self._gate_shortfall()
        if short:
            self._log.info(
                f"holding step 0 until matched: {', '.join(short)} (start.min_subscribers)",
                throttle_duration_sec=_GATE_LOG_S,
            )
            return
        self._gate.cancel()  # type: ignore[no-untyped-call]
        self._gate = None
        self._log.info("every publisher has its start subscribers; publishing step 0")
        self._publish_measurement()

    def _on_republish_timer(self) -> None:
        if self._finished or self._gate is not None:
            return
        waited_ns = time.monotonic_ns() - self._last_publish_ns
        if waited_ns >= self.config.republish_period * _NS_PER_S * 0.999:
            self.republished += 1
            self._publish_measurement()

    def _on_realtime_tick(self) -> None:
        if self._finished:
            return
        now_ns = time.monotonic_ns()
        if now_ns - self._next_tick_ns > self._period_ns:
            self.late_ticks += 1
        self._next_tick_ns = max(self._next_tick_ns + self._period_ns, now_ns)
        if not self._answered_previous:
            self.deadline_misses += 1
        received = self._command_received_ns
        timeout_ns = self.config.command_timeout * _NS_PER_S
        if received is None or now_ns - received > timeout_ns:
            command = (0.0, 0.0)
            self.stale_ticks += 1
            if received is not None:
                self.command_timeouts += 1
                if self.command_timeouts == 1 or self.diagnostics.level != Level.ERROR:
                    self.last_error = f"command timed out (> {self.config.command_timeout:g} s): zero torque"
                    self.diagnostics.check()
                self._warn(
                    f"no torque command for {(now_ns - received) / 1e6:.1f} ms "
                    f"(> command_timeout {self.config.command_timeout * 1e3:g} ms): applying zero torque"
                )
        else:
            command = self._command
        self._step(command, self._command_stamp_ns if command is self._command else -1)
        if self._finished:
            return
        self._answered_previous = False
        self._publish_measurement()

    # ------------------------------------------------------------------------------------- /diagnostics

    def health_counts(self) -> dict[str, int]:
        """Counts judged per diagnostics period (``docs/NODES.md``, smm_sim_node status)."""
        return {
            "steps": self.steps,
            "dropped_invalid": self.dropped_invalid,
            "dropped_unknown_stamp": self.dropped_unknown_stamp,
            "command_timeouts": self.command_timeouts,
            "deadline_misses": self.deadline_misses,
            "late_ticks": self.late_ticks,
            "ticks_on_stop": self.ticks_on_stop,
            "republished": self.republished,
        }

    def _end_period(self) -> None:
        self._windows.roll(self.health_counts())

    def health(self) -> Health:
        """OK / WARN / ERROR by the thresholds of ``docs/NODES.md``."""
        now = self.health_counts()
        last, current = self._windows.last, self._windows.since(now)

        def recent(name: str) -> int:
            return last.get(name, 0) + current.get(name, 0)

        findings: list[tuple[Level, str]] = []
        if self._finished and self.done.exception() is not None:  # type: ignore[no-untyped-call]
            findings.append((Level.ERROR, "the plant diverged"))
        if recent("command_timeouts"):
            findings.append((Level.ERROR, "no valid command in time: zero torque applied"))
        for name in ("dropped_invalid", "dropped_unknown_stamp", "ticks_on_stop", "late_ticks"):
            if recent(name):
                findings.append((Level.WARN, f"{name}: {recent(name)} in the last period"))
        steps = last.get("steps", 0)
        if steps and last.get("deadline_misses", 0) > DEADLINE_MISS_WARN_FRACTION * steps:
            findings.append(
                (Level.WARN, f"{last['deadline_misses']} of {steps} ticks found no answer in time")
            )
        values: dict[str, object] = {
            "loop_rate_hz": f"{self._windows.rate('steps'):.1f}",
            "clock_mode": self._clock_mode,
            **now,
            "last_error": self.last_error,
        }
        return worst(findings, "stepping" if self.steps else "waiting for the first command", values)

    # ------------------------------------------------------------------------------------------ the end

    def _log_statistics(self) -> None:
        self._log.info(statistics_summary(self.statistics()))

    def write_outputs(self) -> None:
        """Write ``record_file`` and ``stats_file`` (when set) with the run so far."""
        config = self.config
        if config.record_file and self._recorder is not None:
            self._recorder.save(Path(config.record_file))
        if config.stats_file:
            path = Path(config.stats_file)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(self.statistics(), indent=2, allow_nan=True))

    def _finish(self) -> None:
        if self._finished:
            return
        self._finished = True
        self._timer.cancel()  # type: ignore[no-untyped-call]
        if self._stats_timer is not None:
            self._stats_timer.cancel()  # type: ignore[no-untyped-call]
        self.write_outputs()
        self._log_statistics()
        self._log.info(f"run complete after {self.steps} steps ({self._plant.time_ns / _NS_PER_S:g} s)")
        unacknowledged = wait_for_delivery(self, _DELIVERY_TIMEOUT_S)
        if unacknowledged:
            self._log.warning(
                f"not every subscriber acknowledged the last messages of {', '.join(unacknowledged)} "
                f"within {_DELIVERY_TIMEOUT_S:g} s; a recorder may miss them"
            )
        self.done.set_result(self.steps)  # type: ignore[no-untyped-call]
        if self._shutdown_when_done:
            self.context.try_shutdown()

    def destroy_node(self) -> None:
        """Write the outputs of an unfinished run (stopped by Ctrl-C), then destroy the node."""
        if hasattr(self, "_finished") and not self._finished:
            self.write_outputs()
        super().destroy_node()  # type: ignore[no-untyped-call]


def _value_at(config: object, name: str) -> Any:
    for part in name.split("."):
        config = getattr(config, part)
    return config


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``smm_sim_node``.

    Exit codes: 0 at the step limit or on Ctrl-C / SIGTERM, 1 when the plant diverged, 2 on a bad parameter.

    Args:
        args: Command line (``--ros-args ...``); None for ``sys.argv``.

    Returns:
        The exit code.
    """
    nodes: list[SimNode] = []

    def create(context: Context) -> SimNode:
        node = SimNode(context=context, shutdown_when_done=True)
        nodes.append(node)
        return node

    try:
        run_node(create, args)
    except SimParameterError as error:
        print(f"{NODE_NAME}: invalid parameter: {error}", file=sys.stderr)
        return 2
    failure = nodes[0].done.exception() if nodes and nodes[0].done.done() else None  # type: ignore[no-untyped-call]
    if failure is not None:
        print(f"{NODE_NAME}: {failure}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
