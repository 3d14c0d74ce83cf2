"""``direct_loop``: ``hw_bridge_node`` and ``controller_node`` in one process, the chain in the I/O thread.

Per feedback frame: decode, step the chain, send, then publish the topics loop's topics with its stamps.
A failing chain sends a safe frame and goes to ERROR. Why and when: docs/LAUNCH.md, "The direct loop".
"""

from __future__ import annotations

import gc
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Final, Unpack

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.context import Context
from rclpy.parameter import Parameter
from smm_controller.controller_node import ControllerNode
from smm_controller.core import Refusal, StepResult
from smm_hw_bridge.bridge_node import HwBridgeNode, judged_exit
from smm_hw_bridge.control_rate import is_control_tick
from smm_hw_bridge.core import BridgeCore
from smm_hw_bridge.transport import Transport
from smm_msgs_py.conversions import JointSample, torque_to_msg
from smm_schema.ranges import bounds

from smm_direct_loop.statistics import LoopStatistics, RunningFigures
from smm_msgs_py import topics
from smm_node_runtime import Admission, ConfigParameters, Health, NodeOptions, refused, run_nodes

__all__ = ["DirectBridgeNode", "DirectControllerNode", "LoopSettings", "main"]

DEFAULT_SWITCH_INTERVAL: Final[float] = 0.0005
"""Default ``sys.setswitchinterval`` of the direct loop's process (s); docs/LAUNCH.md says why."""
DEFAULT_SPIN_US: Final[int] = 150
"""Default ``loop.spin_us`` (us); docs/LAUNCH.md says why."""


class DirectControllerNode(ControllerNode):
    """``controller_node`` whose core is stepped by the direct loop's bridge, not by a topic.

    Raises:
        ValueError: Invalid parameters, or ``chain`` / ``reference_source`` not ``internal``.
    """

    SUBSCRIBES_MEASUREMENT = False

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        if not self.internal_chain or not self.internal_reference:
            self.destroy_node()  # type: ignore[no-untyped-call]
            raise ValueError(
                "the direct loop steps the whole chain itself: chain and reference_source must be 'internal'"
            )
        self._pending: StepResult | None = None
        self.tick_lock: threading.RLock = threading.RLock()
        """Held for a whole tick; parameter changes wait for it (the host gives the bridge's lock)."""

    def command_for(
        self, stamp_ns: int, position: tuple[float, float], effort: tuple[float, float]
    ) -> StepResult:
        """Steps the core on one measurement (rad, N m applied; caller holds :attr:`tick_lock`).

        The messages are built later, by :meth:`publish_answer`, after the frame is sent.

        Returns:
            The torque to send, or why there is none (``chain_failed``: the chain gave no valid torque).
        """
        started = time.perf_counter()
        self.last_input_s = time.monotonic()
        result = self.core.measurement(
            topics.JOINT_STATES, stamp_ns, position, effort, self.get_clock().now().nanoseconds
        )
        if time.perf_counter() - started > self.control_period:
            self.counters.deadline_misses += 1
        self._pending = result
        return result

    def forget_rehearsal(self) -> None:
        """After the preflight's rehearsal: nothing of it is published, the run starts from fresh state."""
        self._pending = None
        self.core.reset()

    def publish_answer(self) -> None:
        """Publishes what the topics loop would for the last measurement, after the frame went out.

        Warnings, ``torque_command``, then ``controller_internals`` and ``reference`` while someone
        subscribes (a recorder, a plot).
        """
        result, self._pending = self._pending, None
        if result is None:
            return
        if isinstance(result, Refusal):
            if result.counter != "duplicates_answered":
                self.warn_refused(result.topic, result.counter, result.message)
            return
        if result.verdict.admission is Admission.RESYNC:
            self.report(topics.JOINT_STATES, result.verdict)
            self.diagnostics.check()
        self.torque_publisher.publish(torque_to_msg(np.array(result.torque), result.stamp_ns))
        if result.duplicate or not self.diagnostics_observed():
            return
        for publisher, message in self.diagnostics_of(result.stamp_ns):
            publisher.publish(message)

    def set_parameters(self, parameter_list: list[Parameter]) -> list[SetParametersResult]:
        """As rclpy's, between two ticks."""
        with self.tick_lock:
            return super().set_parameters(parameter_list)

    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        """As rclpy's, between two ticks (the parameter services call this)."""
        with self.tick_lock:
            return super().set_parameters_atomically(parameter_list)


@dataclass(frozen=True)
class LoopSettings:
    """The direct loop's own settings (parameters of ``hw_bridge_node`` in the direct loop, read-only).

    Attributes:
        switch_interval: ``sys.setswitchinterval`` of the process (s): the longest a thread holding the GIL
            keeps the reader thread waiting once a frame arrived, in [1e-5, 0.1].
        spin_us: The reader polls for the next frame from this long before it is due (one board period
            after the last) until as long after, instead of sleeping (us), in [0, 100000]; 0 = always
            sleep. Saves the wake-up from idle at the cost of that CPU time per period.
    """

    switch_interval: float = field(default=DEFAULT_SWITCH_INTERVAL, metadata=bounds(1e-5, 0.1))
    spin_us: int = field(default=DEFAULT_SPIN_US, metadata=bounds(0, 100_000))

    def __post_init__(self) -> None:
        value = self.switch_interval
        if isinstance(value, bool) or not isinstance(value, float) or not 1e-5 <= value <= 0.1:
            raise ValueError(f"switch_interval must be a number of seconds in [1e-5, 0.1], got {value!r}")
        spin = self.spin_us
        if isinstance(spin, bool) or not isinstance(spin, int) or not 0 <= spin <= 100_000:
            raise ValueError(f"spin_us must be an int in [0, 100000] (us), got {spin!r}")


class DirectBridgeNode(HwBridgeNode):
    """``hw_bridge_node`` that answers each measurement with ``controller``'s chain in its reader thread.

    Args:
        controller: The chain's node (same process, same context).
        **options: The node options every SMM node takes.
    """

    SUBSCRIBES_COMMAND = False
    PROCESS_NAME = "direct_loop"

    def __init__(self, controller: DirectControllerNode, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        try:
            self.settings = ConfigParameters(self, "loop", LoopSettings(), read_only=True)
        except ValueError:
            self.destroy_node()
            raise
        sys.setswitchinterval(self.settings.config.switch_interval)
        self.controller = controller
        controller.tick_lock = self._lock
        self.statistics = LoopStatistics()
        self.publish_us = RunningFigures()
        """Time the ROS side of each tick takes, after the send (us)."""
        self._answered_stamp: int | None = None
        self._last_rx_ns: int | None = None

    def receive_next(self, transport: Transport) -> bytes | None:
        """Sleeps until ``spin_us`` before the next frame is due, then polls for it (``LoopSettings``)."""
        spin_ns = self.settings.config.spin_us * 1000
        last, core = self._last_rx_ns, self.core
        data = None
        feedback = None if core is None else core.last_feedback
        if (
            core is not None
            and feedback is not None
            and not is_control_tick(feedback.tick + 1, core.config.control_divider)
        ):
            spin_ns = 0  # the next frame is one the board holds through: nothing to answer in a hurry
        if spin_ns and last is not None and core is not None:
            due = last + core.config.period_ns
            now = time.monotonic_ns()
            if now < due - spin_ns:
                data = transport.receive((due - spin_ns - now) / 1e9)
            while data is None and time.monotonic_ns() < due + spin_ns:
                data = transport.receive(0.0)
        if data is None:
            data = super().receive_next(transport)
        self._last_rx_ns = None if data is None else time.monotonic_ns()
        return data

    def answer_in_place(self, core: BridgeCore, rx_ns: int) -> bool:
        """Steps the chain on the core's measurement and sends its command; a failing chain faults."""
        self._answered_stamp = None
        stamp_ns = core.stamp_ns
        result = self._stepped(core, stamp_ns)
        if result is None:
            return True
        if isinstance(result, Refusal):
            if result.chain_failed:
                self.fail(f"control chain failed at stamp {stamp_ns} ns: {result.message}")
                return True
            return False
        if not self.take_command(core, result.torque, stamp_ns, rx_ns):
            return False
        self.statistics.on_tick(rx_ns, time.monotonic_ns())
        self._answered_stamp = stamp_ns
        return True

    def rehearse_in_place(self, core: BridgeCore, rx_ns: int) -> bool:
        """The preflight: steps the chain as :meth:`answer_in_place` does, and sends nothing of it."""
        result = self._stepped(core, core.stamp_ns)
        return result is not None and not isinstance(result, Refusal)

    def _stepped(self, core: BridgeCore, stamp_ns: int) -> StepResult | None:
        """The hosted controller's answer to the measurement stamped ``stamp_ns``; None after a law raised."""
        try:
            return self.controller.command_for(stamp_ns, core.position_floats, core.applied_torque_floats)
        except Exception as error:  # a bug in a law: the loop cannot go on
            self.fail(f"control chain failed at stamp {stamp_ns} ns: {type(error).__name__}: {error}")
            return None

    def end_rehearsal(self) -> None:
        """The hosted chain forgets the rehearsal (its reference starts at the first armed measurement)."""
        self.controller.forget_rehearsal()

    def after_feedback(self, sample: JointSample) -> None:
        """The ROS side of the tick after the send, then the next tick's work that needs no measurement.

        The controller's topics, the bridge's, then :meth:`ControllerCore.prepare` (under the tick lock).
        """
        stamp = self._answered_stamp
        if stamp is None:
            return
        started = time.monotonic_ns()
        self.controller.publish_answer()
        core = self.core
        if core is not None:
            self.publish_internals(core, stamp)
        self.publish_us.add((time.monotonic_ns() - started) / 1e3)
        with self.controller.tick_lock:  # the next tick's work that needs no measurement, off its path
            self.controller.core.prepare()

    def on_configure(self, state: Any) -> Any:
        """As the bridge's, and the loop statistics start anew."""
        self.statistics.reset()
        self.publish_us = RunningFigures()
        return super().on_configure(state)

    def on_activate(self, state: Any) -> Any:
        """As the bridge's; what the process holds by now is frozen out of the collector's full passes."""
        gc.freeze()  # a full collection then scans the objects made since, not rclpy's and numpy's
        return super().on_activate(state)

    def health(self) -> Health:
        """The bridge's status plus the loop's periodicity and execution time (ros2_control's figures)."""
        health = super().health()
        values = dict(health.values)
        values.update(self.statistics.values())
        values["publish_time.mean_us"] = f"{self.publish_us.mean:.1f}"
        values["publish_time.max_us"] = f"{self.publish_us.maximum:.1f}"
        return Health(health.level, health.message, values)

    def closing_line(self) -> str:
        """The bridge's closing line, and receive -> send of the commands this host answered."""
        return (
            f"{super().closing_line()}; receive->send "
            f"p50 {self.statistics.execution_percentile_us(50):.0f} us, "
            f"p99 {self.statistics.execution_percentile_us(99):.0f} us over "
            f"{self.statistics.execution_us.count} commands"
        )


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``direct_loop``: ``controller_node`` and ``hw_bridge_node`` in one executor."""
    made: list[DirectControllerNode] = []

    def controller(context: Context) -> DirectControllerNode:
        made.append(DirectControllerNode(context=context))
        return made[0]

    bridges: list[DirectBridgeNode] = []

    def bridge(context: Context) -> DirectBridgeNode:
        bridges.append(DirectBridgeNode(made[0], context=context))
        return bridges[0]

    def run() -> int:
        run_nodes([controller, bridge], args, nodes=(ControllerNode.NODE_NAME, HwBridgeNode.NODE_NAME))
        return judged_exit(0, bridges[0] if bridges else None, "direct_loop")

    return refused(run, "direct_loop")


if __name__ == "__main__":
    sys.exit(main())
