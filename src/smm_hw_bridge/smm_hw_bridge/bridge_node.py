"""``hw_bridge_node``: the bench's I/O device as the plant of the graph, a ROS 2 lifecycle node.

Same topics as ``smm_sim_node`` (publishes ``joint_states``: encoder position rad, effort N m; subscribes
``torque_command``), plus ``hw_bridge_internals``, ``/diagnostics`` and the ``~/estop`` / ``~/rearm``
services. The tick is :class:`~smm_hw_bridge.loop.BridgeLoop`'s, in this node's receiving thread; given an
answerer (the direct loop), it answers each measurement itself and ``torque_command`` is not taken.
Lifecycle, faults and parameters: docs/NODES.md, "hw_bridge_node"; the loop: docs/DESIGN.md.
"""

from __future__ import annotations

import functools
import gc
import secrets
import sys
import threading
import time
import traceback
from collections.abc import Sequence
from typing import Final, Unpack

from rclpy.clock import Clock, ClockType  # type: ignore[attr-defined]
from rclpy.context import Context
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from sensor_msgs.msg import JointState
from smm_msgs_py.conversions import JointSample, internals_to_msg, msg_to_torque, sample_to_joint_state
from smm_msgs_py.errors import InterfaceError
from smm_msgs_py.qos import qos_for_topic, subscription_qos_for_topic
from smm_node_runtime.lifecycle import refuse_invalid_transitions
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from smm_hw_bridge.bridge_health import BridgeCounters
from smm_hw_bridge.bridge_run import AutostartGate, closing_line, judged_exit, realtime_scheduled, run_verdict
from smm_hw_bridge.canopen_config import PARAMETERS, CanopenConfig
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeError
from smm_hw_bridge.device import Device, open_device
from smm_hw_bridge.loop import Answerer, BridgeLoop, ChangeBuffer, Tick
from smm_hw_bridge.loop_statistics import RunningFigures
from smm_hw_bridge.preflight import PreflightConfig, PreflightVerdict, RehearsalRecorder, judge
from smm_hw_bridge.reading import LoopSettings
from smm_hw_bridge.run_verdict import HostVerdictConfig, RunTally
from smm_hw_bridge.transport import LinkConfig
from smm_msgs_py import topics
from smm_node_runtime import (
    ConfigParameters,
    DiagnosticsPublisher,
    Health,
    NodeOptions,
    node_arguments,
    node_main,
)

__all__ = ["INTERNALS_TOPIC", "NODE_NAME", "HwBridgeNode", "main"]

NODE_NAME: Final[str] = "hw_bridge_node"
INTERNALS_TOPIC: Final[str] = topics.HW_BRIDGE_INTERNALS
_FAULT_TRANSITION_S: Final[float] = 0.1
"""How often the executor looks for a signalled fault (s); the safe frame went out at once."""
_AUTOSTART_POLL_S: Final[float] = 0.01
"""How often ``autostart`` looks for a ``torque_command`` publisher (s)."""


class HwBridgeNode(LifecycleNode):
    """The hardware bridge (see the module docstring).

    Args:
        answerer: The controller the loop steps on each measurement (the direct loop), or None: the
            topics loop, ``torque_command`` subscribed. With one the node declares ``loop.*``.
        changes: Where that controller's parameter changes wait for a tick boundary.
        process_name: How the closing line names the process.
        **options: The node options every SMM node takes (:class:`~smm_node_runtime.NodeOptions`).

    Raises:
        ValueError: A parameter value is invalid (the message names it).
    """

    NODE_NAME = NODE_NAME

    def __init__(
        self,
        answerer: Answerer | None = None,
        changes: ChangeBuffer | None = None,
        process_name: str = NODE_NAME,
        **options: Unpack[NodeOptions],
    ) -> None:
        name, arguments = node_arguments(NODE_NAME, options)
        super().__init__(name, **arguments)
        try:
            self._link = ConfigParameters(self, "link", LinkConfig())
            self._canopen = ConfigParameters(self, PARAMETERS, CanopenConfig())
            self._bridge = ConfigParameters(self, "bridge", BridgeConfig())
            self._verdict = ConfigParameters(self, "verdict", HostVerdictConfig(), read_only=True)
            self._gate = ConfigParameters(self, "", AutostartGate(), read_only=True)
            self._preflight = ConfigParameters(self, "preflight", PreflightConfig(), read_only=True)
            settings = None
            if answerer is not None:
                settings = ConfigParameters(self, "loop", LoopSettings(), read_only=True).config
                sys.setswitchinterval(settings.switch_interval)
        except ValueError:
            self.destroy_node()
            raise
        self.process_name = process_name
        self._log = self.get_logger()  # type: ignore[no-untyped-call]
        refuse_invalid_transitions(self)
        self.counters = BridgeCounters()
        self.loop = BridgeLoop(self.counters, answerer, changes, settings)
        """The tick, its core and device while configured."""
        self.publish_us = RunningFigures()
        """Time the ROS side of each answered tick takes, after the send (us)."""
        self._reader: threading.Thread | None = None
        self._stop = threading.Event()
        self._fault_transition = False
        self._run_fault = ""
        """The first fault that took the bridge out of its run (the loop's words), for the verdict."""
        self._joint_states = self.create_publisher(
            JointState, topics.JOINT_STATES, qos_for_topic(topics.JOINT_STATES)
        )
        self._internals = self.create_publisher(
            Float64MultiArray, INTERNALS_TOPIC, qos_for_topic(topics.HW_BRIDGE_INTERNALS)
        )
        if answerer is None:  # with one, torque_command is an output for observation only
            self.create_subscription(
                Float64MultiArray,
                topics.TORQUE_COMMAND,
                self._on_command,
                subscription_qos_for_topic(topics.TORQUE_COMMAND),
            )
        self.create_service(Trigger, "~/estop", self._on_estop)
        self.create_service(Trigger, "~/rearm", self._on_rearm)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(_FAULT_TRANSITION_S, self._on_fault, clock=steady)
        self.diagnostics = DiagnosticsPublisher(self, self.health)
        self._started = False
        self.autostart = self.declare_parameter("autostart", False).value is True
        if self.autostart:
            self._autostart = self.create_timer(_AUTOSTART_POLL_S, self._start, clock=steady)
        if self.autostart and self._verdict.config.ends_run:
            self.create_timer(_FAULT_TRANSITION_S, self._on_plan, clock=steady)
        self._waiting_logged = False
        self.preflight: PreflightVerdict | None = None
        self.preflight_refusal: str | None = None
        """Why the preflight refused to arm (the process then ends), None otherwise."""
        self._preflight_end = 0.0

    # ---- public views -----------------------------------------------------------------------------

    @property
    def core(self) -> BridgeCore | None:
        """The bridge logic while configured."""
        return self.loop.core

    @property
    def device(self) -> Device | None:
        """The open device while configured."""
        return self.loop.device

    @property
    def lifecycle_state(self) -> str:
        """Label of the current lifecycle state (``unconfigured``, ``inactive``, ``active``...)."""
        return str(self._state_machine.current_state[1])

    # ---- autostart and preflight ------------------------------------------------------------------

    def _start(self) -> None:
        """``autostart``: once a controller publishes ``torque_command``, configure, then activate, once.

        Arming before the controller is up would let its start-up starve the loop into a link loss.
        """
        if self._started:
            return
        wanted = self._gate.config.autostart_subscribers
        if (
            self.count_publishers(topics.TORQUE_COMMAND) == 0
            or self.count_subscribers(topics.JOINT_STATES) < wanted
        ):
            if not self._waiting_logged:
                self._log.info(
                    "autostart: waiting for a torque_command publisher (the controller)"
                    + (f" and {wanted} joint_states subscriptions" if wanted else "")
                )
                self._waiting_logged = True
            return
        self._autostart.cancel()  # type: ignore[no-untyped-call]
        self._started = True
        if self.trigger_configure() == TransitionCallbackReturn.SUCCESS:  # type: ignore[no-untyped-call]
            self._begin_preflight()

    def _begin_preflight(self) -> None:
        """Rehearses the loop, output disabled, for ``preflight.duration_s``; then judges. Not in lockstep."""
        core, config = self.core, self._preflight.config
        if core is None:
            return
        if core.config.lockstep or config.duration_s == 0.0:
            why = "lockstep" if core.config.lockstep else "preflight.duration_s = 0"
            self._log.info(f"preflight: skipped ({why})")
            self.trigger_activate()  # type: ignore[no-untyped-call]
            return
        with self.loop.lock:
            divider = core.config.control_divider
            self.loop.rehearsal = RehearsalRecorder(
                core.config.period_ns, divider, config.added_latency_us, every=self._feedback_every(divider)
            )
        self._preflight_end = time.monotonic() + config.duration_s
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        # one wake-up at the end, none during the rehearsal it measures
        self._preflight_timer = self.create_timer(config.duration_s, self._end_preflight, clock=steady)

    def _end_preflight(self) -> None:
        """After the rehearsal: states its figures, then arms, or refuses and ends the process."""
        if time.monotonic() < self._preflight_end:
            return
        self._preflight_timer.cancel()  # type: ignore[no-untyped-call]
        recorder = self.loop.end_rehearsal()
        if recorder is None:
            return
        self.publish_us = RunningFigures()  # the run's figures, not the rehearsal's
        config = self._preflight.config
        verdict = judge(recorder.figures(), self._verdict.config.late_limit, unseen_late=config.unseen_late)
        self.preflight = verdict
        refusal = verdict.refusal(direct_loop=self.loop.answerer is not None, realtime=realtime_scheduled())
        for line in verdict.lines():
            self._log.info(f"preflight: {line}")
        if verdict.holds:  # one logging call per severity: rclpy fixes a call site's severity
            self._log.info(f"preflight: {verdict.figures.rate_hz:g} Hz holds here; arming")
        elif config.force:
            self._log.warning(f"preflight: ARMING ANYWAY (preflight.force): {refusal}")
        else:
            self.preflight_refusal = refusal
            self._log.error(f"preflight: refused to arm: {refusal}")
            self.context.try_shutdown()
            return
        if self.lifecycle_state != "inactive":  # a fault during the rehearsal took it out of configured
            self._log.error(f"preflight: the bridge is {self.lifecycle_state} after rehearsing; not arming")
            return
        self.trigger_activate()  # type: ignore[no-untyped-call]

    # ---- closing ----------------------------------------------------------------------------------

    def destroy_node(self) -> None:
        """Sends safe output, stops the reader thread and closes the device, prints the closing line."""
        if getattr(self, "loop", None) is not None and self.loop.device is not None:
            self._close()
        if getattr(self, "loop", None) is not None and (self.loop.tally is not None or self.autostart):
            print(f"[{self.process_name}] {self.closing_line()}", flush=True)
        super().destroy_node()  # type: ignore[no-untyped-call]

    def closing_line(self) -> str:
        """What the host knows of the run, from the board's feedback (docs/LAUNCH.md, "Exit codes")."""
        statistics = None if self.loop.answerer is None else self.loop.statistics
        return closing_line(self.loop.tally, self.run_verdict(), self.preflight_refusal, statistics)

    def _feedback_every(self, divider: int) -> int:
        """Board ticks between two feedbacks: 1 from a board, N on CANopen (a SYNC a control period)."""
        return divider if self._link.config.transport == "canopen" else 1

    def run_verdict(self) -> str | None:
        """Why this run did not control (never configured, never armed, ...), or None if it did."""
        verdict = run_verdict(self.loop.tally, self.core, waited=self.autostart and not self._started)
        return (
            self.loop.safety_stop
            or verdict
            or (f"it faulted: {self._run_fault}" if self._run_fault else None)
        )

    # ---- lifecycle --------------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Opens the device, waits for valid feedback, locks the board with a safe frame."""
        link, canopen, self._fault_transition = self._link.config, self._canopen.config, False
        self.publish_us = RunningFigures()
        core = BridgeCore(self._bridge.config, host_session=secrets.randbelow(0xFFFFFFFF) + 1)
        divider = core.config.control_divider
        tally = RunTally(core.config.period_ns, self._verdict.config, divider, self._feedback_every(divider))
        source = f"{link.board_address}:{link.board_port}"
        try:
            opener = functools.partial(open_device, link, canopen, core.config)
            why = self.loop.connect(opener, core, tally, link.configure_timeout, source)
        except Exception:  # a bug, not a bad frame (those are counted); the device is closed
            self._log.error(f"configure: waiting for feedback failed:\n{traceback.format_exc()}")
            return TransitionCallbackReturn.FAILURE
        if why is not None:
            self._log.error(f"configure: {why}")
            return TransitionCallbackReturn.FAILURE
        self._stop.clear()
        self._reader = threading.Thread(
            target=self.loop.run,
            args=(self._stop, self._publish, self._log.error),
            name="hw_bridge_reader",
            daemon=True,
        )
        self._reader.start()
        self._log.info(
            f"configured: board session {core.board_session:#010x}, host session {core.host_session:#010x}"
        )
        for line in () if self.loop.device is None else self.loop.device.found:
            self._log.info(f"configured: {line}")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Arms: the output goes live after newer feedback and a command answering it."""
        if self.loop.answerer is not None:  # what the process holds by now is frozen out of full collections
            gc.freeze()
        with self.loop.lock:
            if self.core is None:
                return TransitionCallbackReturn.FAILURE
            try:
                self.core.arm()
            except BridgeError as error:
                self._log.error(f"activate: {error}")
                return TransitionCallbackReturn.FAILURE
        self.diagnostics.check()
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Disarms and sends a safe frame at once."""
        with self.loop.lock:
            if self.core is not None:
                self.core.disarm()
                self.loop.send_safe()
        return TransitionCallbackReturn.ERROR if self._fault_transition else TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Sends a safe frame and closes the device."""
        self._close()
        return TransitionCallbackReturn.ERROR if self._fault_transition else TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Sends a safe frame and closes the device."""
        self._close()
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Sends a safe frame, closes the device; the node goes to ``unconfigured``."""
        self._log.error("error transition: safe output sent, transport closed")
        self._close()
        self._fault_transition = False
        return TransitionCallbackReturn.SUCCESS

    def _close(self) -> None:
        self._stop.set()
        reader, self._reader = self._reader, None
        if reader is not None and reader is not threading.current_thread():
            reader.join(2.0)
        untold = self.loop.detach()
        if untold is not None:
            self._log.warning(f"make safe: {untold}")

    # ---- the receiving thread ---------------------------------------------------------------------

    def _publish(self, tick: Tick) -> None:
        """The ROS side of a tick (receiving thread): ``joint_states``, then what the answerer answered."""
        sample = JointSample(tick.stamp_ns, tick.position, effort=tick.effort)
        self._joint_states.publish(sample_to_joint_state(sample))
        answerer = self.loop.answerer
        if tick.answered is None or answerer is None:
            return
        started = time.monotonic_ns()
        answerer.published()
        with self.loop.lock:
            internals = None if self.core is None else internals_to_msg(self.core.internals, tick.answered)
        if internals is not None:
            self._internals.publish(internals)
        self.publish_us.add((time.monotonic_ns() - started) / 1e3)
        answerer.prepare()

    def _on_command(self, msg: Float64MultiArray) -> None:
        now = time.monotonic_ns()
        try:
            command = msg_to_torque(msg)
        except InterfaceError as error:
            self.counters.bad_commands += 1
            self.counters.last_error = str(error)
            return
        internals = self.loop.on_command(command.values, command.stamp_ns, now)
        if internals is not None:
            self._internals.publish(internals_to_msg(internals, command.stamp_ns))

    # ---- services and faults ----------------------------------------------------------------------

    def _on_estop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if not self.loop.estop():
            response.success, response.message = False, "not configured: no board to stop"
            return response
        self._log.warning("e-stop latched: valves at null until ~/rearm")
        self.diagnostics.check()
        response.success, response.message = True, "e-stop latched on the board"
        return response

    def _on_rearm(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        refusal = self.loop.rearm()
        response.success = refusal is None
        response.message = refusal or "re-arm sent: output needs a fresh measurement and command again"
        return response

    def _on_fault(self) -> None:
        """Executor timer: after a signalled fault (safe output already sent), the error transition."""
        if not self.loop.fault_signalled:  # the usual case: no lock, no work in the executor's thread
            return
        self.loop.fault_signalled = False
        why = self.loop.fault()
        live = self.lifecycle_state in ("active", "inactive")  # not again once the error transition ran
        if why is not None and live and not self._fault_transition:
            self._fault_transition = True
            self._log.error(f"{why}: safe output, error transition")
            planned = self._verdict.config.planned_s
            if self.loop.tally is None or self.loop.tally.before_plan(planned):
                self._run_fault = self._run_fault or why
            else:
                self._log.info(f"the fault came after the planned {planned:g} s live: the verdict stands")
            self.diagnostics.publish()
            if self.lifecycle_state == "active":
                self.trigger_deactivate()  # type: ignore[no-untyped-call]
            elif self.lifecycle_state == "inactive":
                self.trigger_cleanup()  # type: ignore[no-untyped-call]
            if self.autostart and self.loop.safety_stop:  # final, as a refusal at preflight: a person looks
                self._log.error("autostart: the run ends at its safety stop (not configured again)")
                self.context.try_shutdown()
            elif self.autostart and planned > 0.0 and self._run_fault:  # it cannot reach its plan
                self._log.error(
                    f"autostart: the run ends at its fault, before its planned {planned:g} s live (not armed "
                    "again: a person re-arms)"
                )
                self.context.try_shutdown()

    def _on_plan(self) -> None:
        """``verdict.ends_run``: once ``planned_s`` are live, disarm and end the autostarted run (judged)."""
        tally, planned = self.loop.tally, self._verdict.config.planned_s
        if tally is None or tally.live_s() < planned or self.lifecycle_state != "active":
            return  # once done, deactivated: never again
        self._log.info(f"autostart: the planned {planned:g} s live are done: output disabled, the run ends")
        self.trigger_deactivate()  # type: ignore[no-untyped-call]
        self.context.try_shutdown()

    def health(self) -> Health:
        """Link, loss, round trip, board counters, faults, supply pressure; the direct loop's figures."""
        return self.loop.health(self.lifecycle_state, self.publish_us)


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``hw_bridge_node``: builds the node (unconfigured), spins it; exit code: judged_exit."""
    made: list[HwBridgeNode] = []

    def build(context: Context) -> HwBridgeNode:
        made.append(HwBridgeNode(context=context))
        return made[0]

    return judged_exit(node_main(build, args, node=NODE_NAME), made[0] if made else None, NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
