"""``smm_sim_node``: the simulated plant as a ROS 2 node; the logic is :class:`smm_sim.core.SimCore`.

Publishes ``joint_states``, ``ground_truth`` and, in lockstep, ``/clock``; subscribes ``torque_command``.
Topics, parameters, clock modes and exit codes: ``docs/LAUNCH.md`` (smm_sim_node).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from typing import Any, Final, Unpack

from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType  # type: ignore[attr-defined]
from rclpy.context import Context
from rclpy.exceptions import ParameterException
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.task import Future
from rclpy.timer import Timer
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from smm_msgs_py.conversions import JointSample, clock_msg, msg_to_torque, sample_to_joint_state
from smm_msgs_py.errors import InterfaceError
from smm_msgs_py.qos import qos_for_topic, subscription_qos_for_topic
from smm_node_runtime.parameters import ConfigParameters
from smm_node_runtime.run_verdict import EXIT_NOT_CONTROLLED, VerdictConfig
from std_msgs.msg import Float64MultiArray

from smm_msgs_py import topics
from smm_node_runtime import (
    WARN_THROTTLE_S,
    CountWindows,
    DiagnosticsPublisher,
    Health,
    Level,
    NodeOptions,
    SmmNode,
    refused,
    run_node,
    wait_for_delivery,
)
from smm_sim.config import PlantParameters, SimNodeConfig
from smm_sim.core import CommandOutcome, SimCore, statistics_summary

__all__ = ["NODE_NAME", "SimNode", "SimParameterError", "main"]

NODE_NAME: Final[str] = "smm_sim_node"
_NS_PER_S: Final[int] = 1_000_000_000
_STARTUP_ONLY: Final[frozenset[str]] = frozenset({"clock_mode", "start.min_subscribers"})
_GATE_POLL_S: Final[float] = 0.01
_GATE_LOG_S: Final[float] = 2.0
_DELIVERY_TIMEOUT_S: Final[float] = 5.0
"""Longest wait at the end of a run for the subscribers to acknowledge the last messages (s): more than
Fast DDS's 3 s heartbeat period, after which a reliable writer resends what a reader lacks."""


class SimParameterError(ValueError):
    """A parameter of smm_sim_node has an invalid value (the message names the parameter and the value)."""


class SimNode(SmmNode):
    """The simulated SMM plant node: timers, publishers and parameters around :attr:`core`.

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
            self._verdict = ConfigParameters(self, "verdict", VerdictConfig(), read_only=True)
        except ValueError as error:
            self.destroy_node()
            raise SimParameterError(str(error)) from error
        self._shutdown_when_done = shutdown_when_done
        self._log = self.get_logger()  # type: ignore[no-untyped-call]
        # Registered after the declarations, which run the set-parameters callbacks too.
        self.add_on_set_parameters_callback(self._refuse_startup_only)
        config = self._node_parameters.config
        self.core = SimCore(
            self._plant_parameters.config, config, time.monotonic_ns(), verdict=self._verdict.config
        )
        """The simulator's logic: plant, counters, statistics, record (read it from the executor's thread)."""
        self.done: Future = Future()  # type: ignore[no-untyped-call]
        """Completed (result: number of steps) when the run reached ``max_steps`` / ``duration``."""
        self._ended = False
        self._windows = CountWindows({})
        self.diagnostics = DiagnosticsPublisher(self, self.health, on_period=self._end_period)
        self._joint_states_pub = self.create_publisher(
            JointState, topics.JOINT_STATES, qos_for_topic(topics.JOINT_STATES)
        )
        self._ground_truth_pub = self.create_publisher(
            JointState, topics.GROUND_TRUTH, qos_for_topic(topics.GROUND_TRUTH)
        )
        lockstep = config.clock_mode == "lockstep"
        self._clock_pub = (
            self.create_publisher(ClockMsg, topics.CLOCK, qos_for_topic(topics.CLOCK)) if lockstep else None
        )
        self.create_subscription(
            Float64MultiArray,
            topics.TORQUE_COMMAND,
            self._on_command,
            subscription_qos_for_topic(topics.TORQUE_COMMAND),
        )
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._stats_timer: Timer | None = None
        self._gate: Timer | None = None
        if lockstep:
            self._timer = self._create_republish_timer(config)
            if config.start.min_subscribers > 0:
                self._gate = self.create_timer(_GATE_POLL_S, self._on_gate_timer, clock=self._steady)
            else:
                self._publish_measurement()
        else:
            self._timer = self.create_timer(self.core.dt, self._on_realtime_tick, clock=self._steady)
            self._restart_stats_timer(config.stats_period)
            self._publish_measurement()
        plant = self._plant_parameters.config
        limit = self.core.step_limit
        self._log.info(
            f"{config.clock_mode} simulation, period {self.core.dt * 1e3:g} ms, "
            f"{'no step limit' if limit is None else f'{limit} steps'}, "
            f"seed {plant.seed}, disturbance {plant.disturbance}, inertia scale {plant.inertia_scale:g}, "
            f"noise std {list(plant.noise_std)} rad"
        )

    @property
    def config(self) -> SimNodeConfig:
        """The current node configuration."""
        return self._node_parameters.config

    @property
    def plant_parameters(self) -> PlantParameters:
        """The plant parameters (fixed at start-up)."""
        return self._plant_parameters.config

    # ---- parameters and timers ----------------------------------------------------------------------

    def _refuse_startup_only(self, parameters: list[Parameter]) -> SetParametersResult:
        for parameter in parameters:
            if parameter.name in _STARTUP_ONLY and parameter.value != _value_at(self.config, parameter.name):
                return SetParametersResult(
                    successful=False,
                    reason=f"{parameter.name} is fixed at start-up; restart the node to change it",
                )
        return SetParametersResult(successful=True)

    def _on_config_change(self, config: SimNodeConfig) -> None:
        self.core.reconfigure(config)
        if config.clock_mode == "lockstep":
            self._timer.destroy()  # type: ignore[no-untyped-call]
            self._timer = self._create_republish_timer(config)
        else:
            self._restart_stats_timer(config.stats_period)
        self._end_if_finished()

    def _create_republish_timer(self, config: SimNodeConfig) -> Timer:
        return self.create_timer(config.republish_period, self._on_republish_timer, clock=self._steady)

    def _restart_stats_timer(self, period: float) -> None:
        if self._stats_timer is not None:
            self._stats_timer.destroy()  # type: ignore[no-untyped-call]
            self._stats_timer = None
        if period > 0.0:
            self._stats_timer = self.create_timer(period, self._log_statistics, clock=self._steady)

    # ---- commands and ticks -------------------------------------------------------------------------

    def _warn(self, message: str) -> None:
        self._log.warning(message, throttle_duration_sec=WARN_THROTTLE_S)

    def _on_command(self, msg: Float64MultiArray) -> None:
        received_ns = time.monotonic_ns()
        core = self.core
        if core.finished:
            return
        try:
            command = msg_to_torque(msg)
        except InterfaceError as error:
            count = core.reject_command()
            self._warn(
                f"dropped torque command ({type(error).__name__}: {error}); {count} invalid commands so far"
            )
            return
        stamp_ns = command.stamp_ns
        values = (float(command.values[0]), float(command.values[1]))
        outcome = core.on_command(stamp_ns, values, received_ns)
        if outcome is CommandOutcome.UNKNOWN_STAMP:
            self._warn(
                f"dropped torque command for stamp {stamp_ns} ns: no measurement with that stamp was "
                f"published (current {core.stamp_ns} ns); {core.dropped_unknown_stamp} such commands so far"
            )
        elif outcome is CommandOutcome.STEPPED and not self._end_if_finished():
            self._publish_measurement()

    def _on_realtime_tick(self) -> None:
        core = self.core
        if core.finished:
            return
        timed_out_ns = core.tick(time.monotonic_ns())
        if timed_out_ns is not None:
            if core.command_timeouts == 1 or self.diagnostics.level != Level.ERROR:
                self.diagnostics.check()
            self._warn(
                f"no torque command for {timed_out_ns / 1e6:.1f} ms "
                f"(> command_timeout {self.config.command_timeout * 1e3:g} ms): applying zero torque"
            )
        if not self._end_if_finished():
            self._publish_measurement()

    def _on_republish_timer(self) -> None:
        if self._gate is None and self.core.republish_due(time.monotonic_ns()):
            self._publish_measurement()

    def _on_gate_timer(self) -> None:
        assert self._gate is not None
        wanted = [(self._joint_states_pub, self.config.start.min_subscribers), (self._ground_truth_pub, 1)]
        if self._clock_pub is not None:
            wanted.append((self._clock_pub, 1))
        short = [
            f"{publisher.topic_name} {publisher.get_subscription_count()}/{count}"
            for publisher, count in wanted
            if publisher.get_subscription_count() < count
        ]
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

    # ---- publishing ---------------------------------------------------------------------------------

    def _publish_measurement(self) -> None:
        core = self.core
        measurement, truth = core.measurement, core.truth
        stamp_ns = measurement.stamp_ns
        message = sample_to_joint_state(
            JointSample(stamp_ns, measurement.position, None, measurement.applied_torque)
        )
        # The measurement goes first: the controller-side nodes (other processes) start on it.
        now_ns = time.monotonic_ns()
        self._publish(self._joint_states_pub, message)
        core.sent(now_ns)
        # /clock and the ground truth (analysis only) are built and sent only while something listens.
        if self._clock_pub is not None and self._clock_pub.get_subscription_count() > 0:
            self._publish(self._clock_pub, clock_msg(stamp_ns))
        if self._ground_truth_pub.get_subscription_count() > 0:
            sample = JointSample(stamp_ns, truth.position, truth.velocity, truth.applied_torque)
            self._publish(self._ground_truth_pub, sample_to_joint_state(sample))

    def _publish(self, publisher: Publisher, message: object) -> None:
        publisher.publish(message)
        self.core.count_published(publisher.topic_name)

    # ---- /diagnostics and the end of the run ---------------------------------------------------------

    def _end_period(self) -> None:
        self._windows.roll(self.core.health_counts())

    def health(self) -> Health:
        """OK / WARN / ERROR by the thresholds of ``docs/NODES.md`` (:meth:`SimCore.health`)."""
        windows = self._windows
        current = windows.since(self.core.health_counts())
        return self.core.health(windows.last, current, windows.rate("steps"))

    def _log_statistics(self) -> None:
        self._log.info(statistics_summary(self.core.statistics()))

    def _end_if_finished(self) -> bool:
        """End the run once the core finished it (step limit or divergence); True when it is over."""
        core = self.core
        if not core.finished:
            return False
        if self._ended:
            return True
        self._ended = True
        self._timer.cancel()  # type: ignore[no-untyped-call]
        if core.failure is not None:
            self._log.error(str(core.failure))
            core.write_outputs()
            self.done.set_exception(core.failure)  # type: ignore[no-untyped-call]
        else:
            if self._stats_timer is not None:
                self._stats_timer.cancel()  # type: ignore[no-untyped-call]
            core.write_outputs()
            self._log_statistics()
            self._log.info(f"run complete after {core.steps} steps ({core.stamp_ns / _NS_PER_S:g} s)")
            if core.clock_mode == "realtime":
                self._log_verdict()
            unacknowledged = wait_for_delivery(self, _DELIVERY_TIMEOUT_S)
            if unacknowledged:
                self._log.warning(
                    f"not every subscriber acknowledged the last messages of {', '.join(unacknowledged)} "
                    f"within {_DELIVERY_TIMEOUT_S:g} s; a recorder may miss them"
                )
            self.done.set_result(core.steps)  # type: ignore[no-untyped-call]
        if self._shutdown_when_done:
            self.context.try_shutdown()
        return True

    def run_verdict(self) -> str | None:
        """Real time: why the run did not control, or None if it did (:meth:`SimCore.run_verdict`)."""
        return self.core.run_verdict()

    def _log_verdict(self) -> None:
        reason, figures = self.core.run_verdict(), self.core.verdict_figures()
        if reason is None:
            self._log.info(f"run: controlled ({figures})")
        else:
            self._log.error(f"run: did not control: {reason} ({figures})")

    def destroy_node(self) -> None:
        """Write the outputs and verdict of an unfinished run (stopped by Ctrl-C), then destroy the node."""
        if hasattr(self, "_ended") and not self._ended:
            self.core.write_outputs()
            if self.core.clock_mode == "realtime":
                self._log_verdict()
        super().destroy_node()  # type: ignore[no-untyped-call]


def _value_at(config: object, name: str) -> Any:
    for part in name.split("."):
        config = getattr(config, part)
    return config


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``smm_sim_node``.

    Exit codes: 0 at the step limit or on Ctrl-C / SIGTERM, 1 when the plant diverged, 2 on a bad parameter,
    3 when a real-time run did not control (:meth:`SimCore.run_verdict`; judged after Ctrl-C too).

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

    def run() -> int:
        run_node(create, args, node=NODE_NAME)
        done = nodes[0].done if nodes else None
        failure = done.exception() if done is not None and done.done() else None  # type: ignore[no-untyped-call]
        if failure is not None:
            print(f"{NODE_NAME}: {failure}", file=sys.stderr)
            return 1
        reason = nodes[0].run_verdict() if nodes else None
        if reason is not None:
            print(f"{NODE_NAME}: the run did not control: {reason}", file=sys.stderr, flush=True)
            return EXIT_NOT_CONTROLLED
        return 0

    return refused(run, NODE_NAME, (SimParameterError, ParameterException))


if __name__ == "__main__":
    sys.exit(main())
