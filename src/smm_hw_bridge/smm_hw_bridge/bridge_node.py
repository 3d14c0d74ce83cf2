"""``hw_bridge_node``: the bench's I/O board as the plant of the graph, a ROS 2 lifecycle node.

Same topics as ``smm_sim_node`` (publishes ``joint_states``: encoder position rad, effort N m; subscribes
``torque_command``), plus ``hw_bridge_internals``, ``/diagnostics`` and the ``~/estop`` / ``~/rearm``
services; the logic is :class:`BridgeCore`. Lifecycle, faults and parameters: docs/NODES.md,
"hw_bridge_node"; protocol and host state machine: docs/HW_PROTOCOL.md.
"""

from __future__ import annotations

import os
import secrets
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Final, Unpack

import numpy.typing as npt
from rclpy.clock import Clock, ClockType  # type: ignore[attr-defined]
from rclpy.context import Context
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from sensor_msgs.msg import JointState
from smm_msgs_py.conversions import JointSample, internals_to_msg, msg_to_torque, sample_to_joint_state
from smm_msgs_py.errors import InterfaceError
from smm_msgs_py.qos import qos_for_topic, subscription_qos_for_topic
from smm_schema.ranges import at_least, check_bounds
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from smm_hw_bridge.bridge_health import BridgeCounters, bridge_health
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeError, BridgeState
from smm_hw_bridge.preflight import (
    EXIT_PREFLIGHT_REFUSED,
    PreflightConfig,
    PreflightVerdict,
    RehearsalRecorder,
    judge,
)
from smm_hw_bridge.protocol import CommandFrame, Reason, encode
from smm_hw_bridge.run_verdict import EXIT_NOT_CONTROLLED, RunTally, VerdictConfig
from smm_hw_bridge.transport import LinkConfig, Transport, TransportError, open_transport
from smm_msgs_py import topics
from smm_node_runtime import (
    ConfigParameters,
    DiagnosticsPublisher,
    Health,
    NodeOptions,
    node_arguments,
    node_main,
)

__all__ = ["INTERNALS_TOPIC", "LINK_CHECK_S", "NODE_NAME", "HwBridgeNode", "main"]

NODE_NAME: Final[str] = "hw_bridge_node"
INTERNALS_TOPIC: Final[str] = topics.HW_BRIDGE_INTERNALS
LINK_CHECK_S: Final[float] = 0.005
"""Period of the link and host-watchdog check, done by the receiving thread (s)."""
_LINK_CHECK_NS: Final[int] = round(LINK_CHECK_S * 1e9)
_FAULT_TRANSITION_S: Final[float] = 0.1
"""How often the executor looks for a signalled fault (s); the safe frame went out at once."""
_AUTOSTART_POLL_S: Final[float] = 0.01
"""How often ``autostart`` looks for a ``torque_command`` publisher (s)."""
REHEARSAL_STAMP_OFFSET_NS: Final[int] = 3_600_000_000_000
"""Topics loop: the rehearsal's ``joint_states`` are stamped this much (1 h) after the board's tick, so that
the armed run's first measurements are a backward time jump: ``controller_node`` then starts it afresh."""


@dataclass(frozen=True)
class AutostartGate:
    """What ``autostart`` waits for besides a ``torque_command`` publisher.

    Attributes:
        autostart_subscribers: ``joint_states`` subscriptions (the controller, a recorder), so that a
            recording has the first step.
    """

    autostart_subscribers: int = field(default=0, metadata=at_least(0))

    def __post_init__(self) -> None:
        check_bounds(self)


def _refusing_invalid_transitions(callback: Callable[[Any, Any], Any], log: Any) -> Callable[[Any, Any], Any]:
    """``~/change_state`` that answers a transition the current state lacks with ``success: false``.

    rclpy raises ``RCLError`` for an unknown transition id out of the service callback, which ends the
    executor's spin and the process: one mistyped ``ros2 lifecycle set`` would stop the control loop.
    """

    def change_state(request: Any, response: Any) -> Any:
        try:
            return callback(request, response)
        except rclpy_implementation.RCLError as error:
            transition = request.transition
            log.warning(f"change_state: transition {transition.id} {transition.label!r} refused: {error}")
            response.success = False
            return response

    return change_state


class HwBridgeNode(LifecycleNode):
    """The hardware bridge (see the module docstring).

    Args:
        **options: The node options every SMM node takes (:class:`~smm_node_runtime.NodeOptions`).

    Raises:
        ValueError: A parameter value is invalid (the message names it).
    """

    NODE_NAME = NODE_NAME
    SUBSCRIBES_COMMAND: ClassVar[bool] = True
    """False for a host that answers each measurement itself (the direct loop): ``torque_command`` is then
    an output for observation, and a command on it, its own or another publisher's, is not taken."""
    PROCESS_NAME: ClassVar[str] = NODE_NAME
    """How the closing line names the process."""

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        name, arguments = node_arguments(NODE_NAME, options)
        super().__init__(name, **arguments)
        try:
            self._link = ConfigParameters(self, "link", LinkConfig())
            self._bridge = ConfigParameters(self, "bridge", BridgeConfig())
            self._verdict = ConfigParameters(self, "verdict", VerdictConfig(), read_only=True)
            self._gate = ConfigParameters(self, "", AutostartGate(), read_only=True)
            self._preflight = ConfigParameters(self, "preflight", PreflightConfig(), read_only=True)
        except ValueError:
            self.destroy_node()
            raise
        self._log = self.get_logger()  # type: ignore[no-untyped-call]
        change_state = self._service_change_state
        change_state.callback = _refusing_invalid_transitions(change_state.callback, self._log)
        self._lock = threading.RLock()
        self._core: BridgeCore | None = None
        self._transport: Transport | None = None
        self._reader: threading.Thread | None = None
        self._stop = threading.Event()
        self._fault_transition = False
        self._host_fault = ""
        self.counters = BridgeCounters()
        self.tally: RunTally | None = None
        """The run's enabled and late ticks from the admitted feedback, from the first configure on."""
        self._joint_states = self.create_publisher(
            JointState, topics.JOINT_STATES, qos_for_topic(topics.JOINT_STATES)
        )
        self._internals = self.create_publisher(
            Float64MultiArray, INTERNALS_TOPIC, qos_for_topic(topics.HW_BRIDGE_INTERNALS)
        )
        if self.SUBSCRIBES_COMMAND:
            self.create_subscription(
                Float64MultiArray,
                topics.TORQUE_COMMAND,
                self._on_command,
                subscription_qos_for_topic(topics.TORQUE_COMMAND),
            )
        self.create_service(Trigger, "~/estop", self._on_estop)
        self.create_service(Trigger, "~/rearm", self._on_rearm)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._fault_signalled = False
        """Set by the receiving thread or :meth:`fail`: the executor drives the error transition."""
        self.create_timer(_FAULT_TRANSITION_S, self._on_fault, clock=steady)
        self.diagnostics = DiagnosticsPublisher(self, self.health)
        self._started = False
        self.autostart = self.declare_parameter("autostart", False).value is True
        if self.autostart:
            self._autostart = self.create_timer(_AUTOSTART_POLL_S, self._start, clock=steady)
        self._waiting_logged = False
        self.rehearsal: RehearsalRecorder | None = None
        """While the preflight rehearses (output disabled): its arrivals and answers."""
        self.preflight: PreflightVerdict | None = None
        self.preflight_refusal: str | None = None
        """Why the preflight refused to arm (the process then ends), None otherwise."""
        self._preflight_end = 0.0

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
        core, config = self._core, self._preflight.config
        if core is None:
            return
        if core.config.lockstep or config.duration_s == 0.0:
            why = "lockstep" if core.config.lockstep else "preflight.duration_s = 0"
            self._log.info(f"preflight: skipped ({why})")
            self.trigger_activate()  # type: ignore[no-untyped-call]
            return
        with self._lock:
            self.rehearsal = RehearsalRecorder(
                core.config.period_ns, core.config.control_divider, config.added_latency_us
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
        with self._lock:
            recorder, self.rehearsal = self.rehearsal, None
            self.end_rehearsal()
        if recorder is None:
            return
        margin = self._preflight.config.margin
        verdict = judge(recorder.figures(), self._verdict.config.late_limit, margin=margin)
        self.preflight = verdict
        for line in verdict.lines():
            self._log.info(f"preflight: {line}")
        refusal = verdict.refusal(direct_loop=self.direct, realtime=realtime_scheduled())
        if verdict.holds:
            self._log.info(f"preflight: {verdict.figures.rate_hz:g} Hz holds here; arming")
        elif self._preflight.config.force:
            self._log.warning(f"preflight: ARMING ANYWAY (preflight.force): {refusal}")
        else:
            self.preflight_refusal = refusal
            self._log.error(f"preflight: refused to arm: {self.preflight_refusal}")
            self.context.try_shutdown()
            return
        if self.lifecycle_state != "inactive":  # a fault during the rehearsal took it out of configured
            self._log.error(f"preflight: the bridge is {self.lifecycle_state} after rehearsing; not arming")
            return
        self.trigger_activate()  # type: ignore[no-untyped-call]

    @property
    def direct(self) -> bool:
        """True for a host that answers each measurement itself (the direct loop)."""
        return not self.SUBSCRIBES_COMMAND

    def rehearse_in_place(self, core: BridgeCore, rx_ns: int) -> bool:
        """Hook of the direct loop: steps the chain on the measurement, sends nothing (lock held).

        True if it answered; the topics loop publishes the measurement to its controller instead: False.
        """
        return False

    def end_rehearsal(self) -> None:
        """Hook called when the rehearsal ends, before arming (lock held): the chain starts the run afresh."""

    def destroy_node(self) -> None:
        """Sends safe output, stops the reader thread and closes the transport, prints the closing line."""
        if getattr(self, "_transport", None) is not None:
            self._close()
        if getattr(self, "tally", None) is not None or getattr(self, "autostart", False):
            print(f"[{self.PROCESS_NAME}] {self.closing_line()}", flush=True)
        super().destroy_node()  # type: ignore[no-untyped-call]

    def closing_line(self) -> str:
        """What the host knows of the run, from the board's feedback frames (docs/LAUNCH.md, "Exit codes")."""
        tally = self.tally
        reason = self.run_verdict()
        if self.preflight_refusal is not None:
            return "host: refused to arm at preflight (its figures and reason above); no output went live"
        if tally is None:
            return f"host: no feedback frame counted; did not control: {reason}"
        verdict = "controlled" if reason is None else f"did not control: {reason}"
        return f"host: {tally.figures()}, from the board's feedback frames; {verdict}"

    def run_verdict(self) -> str | None:
        """Why this run did not control (never configured, never armed, ...), or None if it did."""
        if self.tally is None:
            if self.autostart and not self._started:
                return "the bridge never armed: autostart waited for the controller to the end"
            return "the bridge was never configured: no valid feedback from the board"
        reason = self.tally.verdict()
        core = self._core
        if reason is not None and not self.tally.armed and core is not None and core.refused:
            refused = ", ".join(
                f"{why.value} {count}" for why, count in sorted(core.refused.items(), key=str)
            )
            reason += f" (commands refused: {refused})"
        return reason

    # ---- public views -----------------------------------------------------------------------------

    @property
    def core(self) -> BridgeCore | None:
        """The bridge logic while configured."""
        return self._core

    @property
    def transport(self) -> Transport | None:
        """The open transport while configured."""
        return self._transport

    @property
    def lifecycle_state(self) -> str:
        """Label of the current lifecycle state (``unconfigured``, ``inactive``, ``active``...)."""
        return str(self._state_machine.current_state[1])

    # ---- lifecycle --------------------------------------------------------------------------------

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Opens the transport, waits for valid feedback, locks the board with a safe frame."""
        link = self._link.config
        self._fault_transition = False
        self._host_fault = ""
        try:
            transport = open_transport(link)
        except TransportError as error:
            self._log.error(f"configure: {error}")
            return TransitionCallbackReturn.FAILURE
        core = BridgeCore(self._bridge.config, host_session=secrets.randbelow(0xFFFFFFFF) + 1)
        deadline = time.monotonic() + link.configure_timeout
        try:
            while core.last_feedback is None and time.monotonic() < deadline:
                data = transport.receive(min(0.05, max(deadline - time.monotonic(), 0.0)))
                if data is not None:
                    core.on_datagram(data, time.monotonic_ns())
        except Exception:  # a bug, not a bad frame (those are counted): fail without leaking the socket
            transport.close()
            self._log.error(f"configure: waiting for feedback failed:\n{traceback.format_exc()}")
            return TransitionCallbackReturn.FAILURE
        if core.last_feedback is None:
            transport.close()
            rejected = {reason.value: count for reason, count in core.rejected.items()}
            why = (
                "the board speaks another protocol version"
                if Reason.VERSION in core.rejected
                else "no valid feedback"
            )
            self._log.error(
                f"configure: {why} from {link.board_address}:{link.board_port} within "
                f"{link.configure_timeout} s (rejected: {rejected}, transport dropped: {transport.dropped})"
            )
            return TransitionCallbackReturn.FAILURE
        with self._lock:
            self._core, self._transport = core, transport
            if self.tally is None:
                self.tally = RunTally(
                    core.config.period_ns, self._verdict.config, core.config.control_divider
                )
            self._send_safe()
        self._stop.clear()
        self._reader = threading.Thread(target=self._read_loop, name="hw_bridge_reader", daemon=True)
        self._reader.start()
        self._log.info(
            f"configured: board session {core.board_session:#010x}, host session {core.host_session:#010x}"
        )
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Arms: the output goes live after newer feedback and a command answering it."""
        with self._lock:
            if self._core is None:
                return TransitionCallbackReturn.FAILURE
            try:
                self._core.arm()
            except BridgeError as error:
                self._log.error(f"activate: {error}")
                return TransitionCallbackReturn.FAILURE
        self.diagnostics.check()
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Disarms and sends a safe frame at once."""
        with self._lock:
            if self._core is not None:
                self._core.disarm()
                self._send_safe()
        return TransitionCallbackReturn.ERROR if self._fault_transition else TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Sends a safe frame and closes the transport."""
        self._close()
        return TransitionCallbackReturn.ERROR if self._fault_transition else TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Sends a safe frame and closes the transport."""
        self._close()
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Sends a safe frame, closes the transport; the node goes to ``unconfigured``."""
        self._log.error("error transition: safe output sent, transport closed")
        self._close()
        self._fault_transition = False
        return TransitionCallbackReturn.SUCCESS

    def _close(self) -> None:
        self._stop.set()
        reader, self._reader = self._reader, None
        if reader is not None and reader is not threading.current_thread():
            reader.join(2.0)
        with self._lock:
            if self._core is not None:
                self._core.disarm()
                self._send_safe()
            if self._transport is not None:
                self._transport.close()
            self._transport = None

    # ---- I/O --------------------------------------------------------------------------------------

    def _send_safe(self) -> None:
        """Sends the frame the core wants now; after disarm that is a safe frame (lock held)."""
        core, transport = self._core, self._transport
        if core is None or transport is None:
            return
        frame = core.next_frame(time.monotonic_ns())
        if frame is not None:
            self._transmit(frame)

    def _transmit(self, frame: CommandFrame) -> None:
        assert self._transport is not None
        try:
            self._transport.send(encode(frame))
        except TransportError as error:
            self.counters.last_error = str(error)
            return
        self.counters.frames_sent += 1
        if not frame.enabled:
            self.counters.safe_frames_sent += 1
        elif self.tally is not None:
            self.tally.armed = True

    def _read_loop(self) -> None:
        next_check = 0
        while not self._stop.is_set():
            transport = self._transport
            if transport is None:
                return
            try:
                data = self.receive_next(transport)
            except (TransportError, OSError) as error:
                self.counters.last_error = str(error)
                if self._stop.wait(LINK_CHECK_S):
                    return
                data = None
            try:
                if data is not None:
                    self._on_datagram(data)
                now = time.monotonic_ns()
                if data is None or now >= next_check:  # after the answer went out, not before
                    next_check = now + _LINK_CHECK_NS
                    self._check(now)
            except Exception as error:  # a bug in the host's handling: the reader must outlive it
                self._handling_failed(error)

    def receive_next(self, transport: Transport) -> bytes | None:
        """The next datagram, or None after :data:`LINK_CHECK_S` without one (the receiving thread's wait)."""
        return transport.receive(LINK_CHECK_S)

    def _handling_failed(self, error: Exception) -> None:
        """The bridge's own handling of a datagram raised: its state is not to be trusted, a host fault."""
        if not self._host_fault:  # once: until the error transition the next datagrams may raise too
            self._log.error(f"reader: handling a datagram raised:\n{traceback.format_exc()}")
        try:
            self.fail(f"datagram handling raised {type(error).__name__}: {error}")
        except Exception:  # the safe frame failed too; the host fault is set, the timer still fails over
            self._log.error(f"reader: sending the safe frame raised:\n{traceback.format_exc()}")

    def _on_datagram(self, data: bytes) -> None:
        now = time.monotonic_ns()
        with self._lock:
            core = self._core
            if core is None or self._transport is None:
                return
            frame = core.on_datagram(data, now)
            # lockstep: the board re-sends its unanswered feedback; so do we (a DDS sample may be lost)
            resent = core.config.lockstep and core.last_rejection is Reason.DUPLICATE
            if frame is None and not resent:
                return
            # the controller answers every Nth board tick (bridge.control_divider); the board holds between
            armed = core.state in (BridgeState.ARMING, BridgeState.ARMED)
            publish = armed and core.control_tick
            rehearsal = None if armed or frame is None else self.rehearsal
            control = rehearsal is not None and core.control_tick
            rehearsed = False
            tick = 0
            if rehearsal is not None:
                tick = core.stamp_ns // core.config.period_ns
                rehearsal.on_feedback(tick, now, control)
                rehearsed = control and self.rehearse_in_place(core, now)
            answered = publish and self.answer_in_place(core, now)
            if not answered and core.needs_frame(now):
                out = core.next_frame(now)
                if out is not None:
                    self._transmit(out)
            if frame is not None and self.tally is not None:  # the run's figures: after the send
                self.tally.on_feedback(frame)
            if rehearsed and rehearsal is not None:
                rehearsal.on_answer(tick, time.monotonic_ns())
            if not publish and (not control or self.direct):
                return
            stamp = core.stamp_ns + (0 if publish else REHEARSAL_STAMP_OFFSET_NS)
            sample = JointSample(stamp, core.position, effort=core.applied_torque)
        self._joint_states.publish(sample_to_joint_state(sample))
        if publish:
            self.after_feedback(sample)

    def answer_in_place(self, core: BridgeCore, rx_ns: int) -> bool:
        """Hook of a host that answers the core's measurement in its receiving thread (lock held, none sent).

        Called for every admitted measurement while arming or armed (and, in lockstep, for the board's
        re-sent unanswered one). The topics loop answers on ``torque_command`` instead, so here: False
        (nothing sent).
        """
        return False

    def after_feedback(self, sample: JointSample) -> None:
        """Hook called in the receiving thread after ``joint_states`` went out (lock released)."""

    def take_command(self, core: BridgeCore, torque: npt.ArrayLike, stamp_ns: int, rx_ns: int) -> bool:
        """Hands one torque command to the core and sends the frame it gives (lock held); True if accepted.

        ``torque`` (alpha, beta) (N m): any array-like :meth:`BridgeCore.on_command` takes; a tuple of two
        Python floats is its fast path.
        """
        refusal = core.on_command(torque, stamp_ns, rx_ns)
        if refusal is not None:
            self.counters.refused[refusal.value] = self.counters.refused.get(refusal.value, 0) + 1
            return False
        self.counters.commands += 1
        frame = core.next_frame(rx_ns)
        if frame is not None:
            self._transmit(frame)
        return True

    def publish_internals(self, core: BridgeCore, stamp_ns: int) -> None:
        """Publishes ``hw_bridge_internals`` of the last command, stamped ``stamp_ns``."""
        with self._lock:
            message = internals_to_msg(core.internals, stamp_ns)
        self._internals.publish(message)

    def fail(self, reason: str) -> None:
        """A host-side fault (the loop cannot go on): safe frame now, then the error transition.

        Callable from any thread; the steady timer drives the lifecycle as for board fault bits.
        """
        with self._lock:
            self.counters.last_error = reason
            self._host_fault = reason
            if self._core is not None:
                self._core.disarm()
                self._send_safe()
        self._fault_signalled = True

    def _on_command(self, msg: Float64MultiArray) -> None:
        now = time.monotonic_ns()
        try:
            command = msg_to_torque(msg)
        except InterfaceError as error:
            self.counters.bad_commands += 1
            self.counters.last_error = str(error)
            return
        with self._lock:
            core = self._core
            if core is None or self._transport is None:
                return
            rehearsal = self.rehearsal
            if rehearsal is not None:  # the answer to a rehearsed measurement: timed, never sent
                tick = (command.stamp_ns - REHEARSAL_STAMP_OFFSET_NS) // core.config.period_ns
                rehearsal.on_answer(tick, now)
                return
            if not self.take_command(core, command.values, command.stamp_ns, now):
                return
            internals = internals_to_msg(core.internals, command.stamp_ns)
        self._internals.publish(internals)

    # ---- services and checks ----------------------------------------------------------------------

    def _on_estop(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self._lock:
            if self._core is None or self._transport is None:
                response.success, response.message = False, "not configured: no board to stop"
                return response
            self._core.estop()
            self._send_safe()
        self._log.warning("e-stop latched: valves at null until ~/rearm")
        self.diagnostics.check()
        response.success, response.message = True, "e-stop latched on the board"
        return response

    def _on_rearm(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self._lock:
            if self._core is None or self._transport is None:
                response.success, response.message = False, "not configured"
                return response
            try:
                self._core.rearm()
            except BridgeError as error:
                response.success, response.message = False, str(error)
                return response
            self._send_safe()
        response.success = True
        response.message = "re-arm sent: output needs a fresh measurement and command again"
        return response

    def _check(self, now: int) -> None:
        """Receiving thread, every ``LINK_CHECK_S``: host watchdog and link check; a fault is signalled.

        In this thread, not an executor timer: a timer's wake-ups would take the GIL at random points of
        the loop's ticks (docs/LAUNCH.md, "The direct loop").
        """
        with self._lock:
            core = self._core
            if core is None or self._transport is None:
                return
            core.check_link(now)
            if core.state == BridgeState.ARMED and core.needs_frame(now) and core.output_live:
                out = core.next_frame(now)  # host watchdog: safe output although feedback stopped
                if out is not None:
                    self._transmit(out)
            fault = core.state == BridgeState.FAULT or bool(self._host_fault)
        if fault and not self._fault_transition:
            self._fault_signalled = True

    def _on_fault(self) -> None:
        """Executor timer: after a signalled fault (safe output already sent), the error transition."""
        if not self._fault_signalled:  # the usual case: no lock, no work in the executor's thread
            return
        self._fault_signalled = False
        with self._lock:
            core = self._core
            if core is None:
                return
            fault = core.state == BridgeState.FAULT or bool(self._host_fault)
        if fault and not self._fault_transition:
            self._fault_transition = True
            last = core.last_feedback
            bits = 0 if last is None else last.faults
            why = f"host fault ({self._host_fault})" if self._host_fault else f"board fault bits {bits:#06x}"
            self._log.error(f"{why}: safe output, error transition")
            self.diagnostics.publish()
            if self.lifecycle_state == "active":
                self.trigger_deactivate()  # type: ignore[no-untyped-call]
            elif self.lifecycle_state == "inactive":
                self.trigger_cleanup()  # type: ignore[no-untyped-call]

    def health(self) -> Health:
        """Link, loss, round trip, board counters, faults, supply pressure (:func:`bridge_health`)."""
        now = time.monotonic_ns()
        with self._lock:
            dropped = {} if self._transport is None else self._transport.dropped
            return bridge_health(
                self._core,
                self.counters,
                dropped,
                host_fault=self._host_fault,
                lifecycle=self.lifecycle_state,
                now_ns=now,
            )


def realtime_scheduled() -> bool:
    """True when this process runs under a real-time policy (SCHED_FIFO or SCHED_RR)."""
    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)
    except (AttributeError, OSError):  # not Linux
        return False


def judged_exit(code: int, node: HwBridgeNode | None, name: str) -> int:
    """``code``, or :data:`EXIT_NOT_CONTROLLED` when ``node`` was to start itself and its run did not control.

    A bridge driven by hand (no ``autostart``) is not judged: the closing line says what it saw.
    """
    if code != 0 or node is None or not node.autostart:
        return code
    if node.preflight_refusal is not None:
        print(f"{name}: refused to arm at preflight: {node.preflight_refusal}", file=sys.stderr, flush=True)
        return EXIT_PREFLIGHT_REFUSED
    reason = node.run_verdict()
    if reason is None:
        return code
    print(f"{name}: the run did not control: {reason}", file=sys.stderr, flush=True)
    return EXIT_NOT_CONTROLLED


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``hw_bridge_node``: builds the node (unconfigured), spins it; exit code: judged_exit."""
    made: list[HwBridgeNode] = []

    def build(context: Context) -> HwBridgeNode:
        made.append(HwBridgeNode(context=context))
        return made[0]

    return judged_exit(node_main(build, args, node=NODE_NAME), made[0] if made else None, NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
