"""hw_bridge_node against the emulator (in-process thread, loopback UDP): lifecycle safe output, e-stop,
fault bits -> error transition, reboot, diagnostics, and 10,000 fuzzed frames into the running socket.
"""

from __future__ import annotations

import json
import socket
import threading
import time
import zlib
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from smm_hw_bridge.core import BridgeState
from smm_hw_bridge.protocol import Reason
from udp_bench import (
    LOOPBACK,
    PARSE_AND_SESSION_REASONS,
    feedback_frame,
    free_port,
    parse_and_session_rejections,
)

pytestmark = pytest.mark.ros

TORQUE = (0.3, -0.2)


LOOPS = ("topics", "direct")
DIRECT_CONTROLLER = {"chain": "internal", "reference_source": "internal", "algorithm": "pid"}
"""controller_node's parameters in the direct loop (the PID on the default reference: a live output)."""


class Bench:
    """Emulator thread + bridge node + a peer node answering every measurement with TORQUE.

    ``loop="direct"``: the direct loop's bridge and controller_node instead (the peer only counts).
    ``counter_bits``: the width of the board's encoder counters, and the bridge's.
    """

    def __init__(
        self,
        context: Any,
        mode: str = "realtime",
        answer: bool = True,
        loop: str = "topics",
        counter_bits: int = 32,
        **parameters: Any,
    ) -> None:
        import rclpy
        from sensor_msgs.msg import JointState
        from smm_bench_emulator.board import BoardConfig
        from smm_bench_emulator.emulator import Emulator, EmulatorConfig
        from smm_hw_bridge.bridge_node import HwBridgeNode
        from smm_msgs_py.conversions import stamp_to_ns, torque_to_msg
        from smm_msgs_py.qos import qos_for_topic
        from smm_sim.plant import PlantConfig
        from std_msgs.msg import Float64MultiArray

        from smm_msgs_py import topics
        from smm_node_runtime import make_executor

        host_port, board_port = free_port(), free_port()
        self.emulator = Emulator(
            EmulatorConfig(
                board=BoardConfig(
                    plant=PlantConfig(encoder_counts_per_rev=1 << 20),
                    adc_noise=0.0,
                    counter_bits=counter_bits,
                ),
                bind=(LOOPBACK, board_port),
                host=(LOOPBACK, host_port),
                control=(LOOPBACK, free_port()),
                mode=mode,  # type: ignore[arg-type]
                # lockstep as the product pairs it (bridge.lockstep): only an enabled answer ticks the board,
                # so safe frames sent while the controller is slow never run the board ahead of it
                lockstep_trigger="enabled" if mode == "lockstep" else "any",
            )
        )
        self.thread = threading.Thread(target=self.emulator.run, daemon=True)
        self.thread.start()
        # The emulator thread shares this process's GIL: links and staleness get 1 s of slack here.
        overrides = {
            "link.bind_port": host_port,
            "link.board_port": board_port,
            "link.configure_timeout": 2.0,
            "bridge.link_timeout_ns": 1_000_000_000,
            "bridge.admission.stale_ns": 1_000_000_000,
            "bridge.lockstep": mode == "lockstep",
            "bridge.encoder.counter_bits": counter_bits,
            **parameters,
        }
        self.controller: Any = None
        if loop == "direct":
            from smm_direct_loop.host import compose

            self.controller, self.node = compose(context, DIRECT_CONTROLLER, overrides)
            self.hosted: Any = self.node.loop.answerer
        else:
            self.node = HwBridgeNode(context=context, parameter_overrides=overrides)
        self.peer = rclpy.create_node("test_controller", context=context)
        self.answer = answer and loop == "topics"
        self.measurements = 0
        self.internals: list[Any] = []
        self.diagnostics: list[Any] = []
        commands = self.peer.create_publisher(
            Float64MultiArray, topics.TORQUE_COMMAND, qos_for_topic(topics.TORQUE_COMMAND)
        )

        def on_measurement(msg: JointState) -> None:
            self.measurements += 1
            if self.answer:
                commands.publish(torque_to_msg(np.asarray(TORQUE), stamp_to_ns(msg.header.stamp)))

        self.peer.create_subscription(
            JointState, topics.JOINT_STATES, on_measurement, qos_for_topic(topics.JOINT_STATES)
        )
        from diagnostic_msgs.msg import DiagnosticArray

        self.peer.create_subscription(Float64MultiArray, "hw_bridge_internals", self.internals.append, 100)
        self.peer.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append, 100)
        self.executor = make_executor(context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.peer)
        if self.controller is not None:
            self.executor.add_node(self.controller)

    @property
    def board(self) -> Any:
        return self.emulator.board

    def spin_until(self, predicate: Any, timeout_s: float = 10.0) -> bool:
        from ros_harness import spin_until

        return spin_until(self.executor, predicate, timeout_s)

    def live(self) -> bool:
        return self.board.output_codes() != (0, 0)

    def start(self) -> None:
        from rclpy.lifecycle import TransitionCallbackReturn

        assert self.node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert self.node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert self.spin_until(self.live), "the output never went live"

    def close(self) -> None:
        self.executor.shutdown()
        self.emulator.running = False
        self.thread.join(5.0)
        self.emulator.close()
        if self.node.device is not None:
            self.node.trigger_shutdown()
        self.node.destroy_node()
        self.peer.destroy_node()
        if self.controller is not None:
            self.controller.destroy_node()

    def bridge_statuses(self) -> list[Any]:
        """The bridge's /diagnostics statuses received so far (the direct loop's controller has its own)."""
        return [s for array in self.diagnostics for s in array.status if "hw_bridge_node" in s.name]


@pytest.fixture(params=LOOPS)
def bench(ros_context: Any, request: pytest.FixtureRequest) -> Iterator[Bench]:
    harness = Bench(ros_context, loop=request.param)
    try:
        yield harness
    finally:
        harness.close()


def control(bench: Bench, request: dict[str, object]) -> dict[str, object]:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(5.0)
        sock.sendto(json.dumps(request).encode(), bench.emulator.control_address)  # type: ignore[arg-type]
        reply: dict[str, object] = json.loads(sock.recv(65536))
        return reply


def assert_safe_now(bench: Bench) -> None:
    """The board got a safe frame: valves at null, not by its own watchdog (validity is 5000 ticks here).

    Null codes alone are not enough: the direct loop's PID may command codes (0, 0) while enabled.
    """
    assert bench.spin_until(lambda: not bench.live() and not bench.board.status_enabled, 2.0)
    assert bench.board.last_feedback is not None
    assert not bench.board.last_feedback.status & 0x0008, "nulled by the board's watchdog, not a safe frame"


def test_configure_without_a_board_fails_and_stays_unconfigured(ros_context: Any) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn
    from smm_hw_bridge.bridge_node import HwBridgeNode

    node = HwBridgeNode(
        context=ros_context,
        parameter_overrides={
            "link.bind_port": free_port(),
            "link.board_port": free_port(),
            "link.configure_timeout": 0.2,
        },
    )
    try:
        assert node.trigger_configure() == TransitionCallbackReturn.FAILURE
        assert node.lifecycle_state == "unconfigured" and node.device is None
    finally:
        node.destroy_node()


def test_invalid_parameters_are_rejected_with_their_reason(ros_context: Any) -> None:
    from rclpy.parameter import Parameter
    from smm_hw_bridge.bridge_node import HwBridgeNode

    with pytest.raises(ValueError, match="board_address"):
        HwBridgeNode(context=ros_context, parameter_overrides={"link.board_address": "board.local"})
    node = HwBridgeNode(context=ros_context)
    try:
        for name, value in (
            ("bridge.stale_periods", 0),
            ("bridge.valve.gain", [1.0, -1.0]),
            ("link.board_port", 70000),
        ):
            result = node.set_parameters([Parameter(name, value=value)])[0]
            assert not result.successful and result.reason
    finally:
        node.destroy_node()


@pytest.mark.parametrize("loop", LOOPS)
def test_every_lifecycle_transition_sends_safe_output(ros_context: Any, loop: str) -> None:
    # the board's watchdog cannot be the reason
    bench = Bench(ros_context, loop=loop, **{"bridge.validity_ticks": 5000})
    try:
        from rclpy.lifecycle import TransitionCallbackReturn

        assert bench.node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert bench.spin_until(lambda: bench.board.host_session == bench.node.core.host_session)
        bench.spin_until(lambda: False, 0.1)
        assert not bench.live() and bench.measurements == 0  # configured: no output, no measurements
        # active -> deactivate, inactive -> cleanup, active -> shutdown: each sends a safe frame
        for transition, from_active in (("deactivate", True), ("cleanup", False), ("shutdown", True)):
            if bench.node.lifecycle_state == "unconfigured":
                assert bench.node.trigger_configure() == TransitionCallbackReturn.SUCCESS
            if from_active:
                assert bench.node.trigger_activate() == TransitionCallbackReturn.SUCCESS
                assert bench.spin_until(bench.live), f"no live output before {transition}"
            safe_before = bench.node.counters.safe_frames_sent
            assert getattr(bench.node, f"trigger_{transition}")() == TransitionCallbackReturn.SUCCESS
            assert bench.node.counters.safe_frames_sent > safe_before
            assert_safe_now(bench)
    finally:
        bench.close()


@pytest.mark.parametrize("loop", LOOPS)
def test_a_transition_the_state_lacks_is_refused_and_the_loop_runs_on(ros_context: Any, loop: str) -> None:
    """``ros2 lifecycle set`` of a transition not valid now (by id): success false, no end of the process."""
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState
    from rclpy.lifecycle import TransitionCallbackReturn

    bench = Bench(ros_context, loop=loop)
    try:
        assert bench.node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert bench.node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert bench.spin_until(bench.live)
        client = bench.peer.create_client(
            ChangeState, f"{bench.node.get_fully_qualified_name()}/change_state"
        )
        assert bench.spin_until(client.service_is_ready)
        for transition in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE, 99):
            future = client.call_async(ChangeState.Request(transition=Transition(id=transition)))
            assert bench.spin_until(future.done), transition  # the executor spins on: nothing raised
            assert future.result().success is False, transition
        assert bench.node.lifecycle_state == "active"
        before = bench.measurements
        assert bench.spin_until(lambda: bench.measurements > before + 10 and bench.live())
    finally:
        bench.close()


@pytest.mark.parametrize("loop", LOOPS)
def test_no_executor_timer_wakes_faster_than_10_hz_while_the_loop_runs(ros_context: Any, loop: str) -> None:
    """The link check and host watchdog run in the reader thread: no timer takes the GIL within ticks."""
    from rclpy.lifecycle import TransitionCallbackReturn

    bench = Bench(ros_context, loop=loop)
    try:
        assert bench.node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert bench.node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert bench.spin_until(bench.live)
        nodes = [bench.node, *([bench.controller] if loop == "direct" else [])]
        periods = [t.timer_period_ns for node in nodes for t in node.timers if not t.is_canceled()]
        assert periods and min(periods) >= 100_000_000, periods
    finally:
        bench.close()


def test_take_command_takes_a_tuple_of_two_floats_and_the_board_applies_its_codes(ros_context: Any) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn
    from smm_hw_bridge.valve_output import ValveOutput

    # no peer answers; a long host watchdog and validity keep the one command on the valves
    overrides = {"bridge.host_watchdog_ns": 5_000_000_000, "bridge.validity_ticks": 5000}
    bench = Bench(ros_context, answer=False, **overrides)
    try:
        node = bench.node
        assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        core = node.core
        taken: list[bool] = []

        def take() -> bool:
            with node.loop.lock:
                if core.last_feedback.host_session == core.host_session and core.stamp_ns > 0:
                    taken.append(node.loop.take_command(TORQUE, core.stamp_ns, time.monotonic_ns()))
                return bool(taken) and taken[-1] and core.output_live

        assert bench.spin_until(take), f"never taken in {len(taken)} tries, refused: {node.counters.refused}"
        expected = ValveOutput(core.config.valve).step(TORQUE, core.config.period_ns * 1e-9).codes
        assert tuple(int(code) for code in core.internals["codes"]) == expected != (0, 0)
        assert bench.spin_until(lambda: bench.board.output_codes() == expected, 5.0)
    finally:
        bench.close()


def test_estop_service_latches_on_the_board_until_rearm(bench: Bench) -> None:
    from std_srvs.srv import Trigger

    bench.start()
    estop = bench.peer.create_client(Trigger, "/hw_bridge_node/estop")
    rearm = bench.peer.create_client(Trigger, "/hw_bridge_node/rearm")
    assert bench.spin_until(lambda: estop.service_is_ready() and rearm.service_is_ready())
    future = estop.call_async(Trigger.Request())
    assert bench.spin_until(future.done)
    assert future.result().success
    assert bench.spin_until(lambda: bench.board.estop_latched and not bench.live())
    bench.spin_until(lambda: False, 0.2)  # the controller keeps commanding: nothing reaches the valves
    assert bench.board.estop_latched and not bench.live()
    future = rearm.call_async(Trigger.Request())
    assert bench.spin_until(future.done)
    assert future.result().success
    assert bench.spin_until(bench.live), "output did not resume after re-arm"
    assert not bench.board.estop_latched


def test_board_fault_bits_give_safe_output_an_error_diagnostic_and_the_error_transition(bench: Bench) -> None:
    bench.start()
    assert control(bench, {"faults": 2})["ok"] is True
    assert bench.spin_until(lambda: bench.node.lifecycle_state == "unconfigured")
    assert not bench.live()

    def errors() -> list[Any]:
        return [s for s in bench.bridge_statuses() if s.level == b"\x02"]

    assert bench.spin_until(lambda: bool(errors()), 5.0), "no ERROR diagnostic"
    assert "fault" in errors()[0].message
    values = {kv.key: kv.value for kv in errors()[0].values}
    assert values["fault_bits"] == "0x0002"


def test_reboot_mid_run_keeps_output_disabled_until_reactivation(bench: Bench) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn

    bench.start()
    reply = control(bench, {"reboot": True})  # carried out inside the emulator's loop
    applied = int(reply["applied"])
    assert bench.spin_until(lambda: bench.node.core.state.value == "session_lost")
    bench.spin_until(lambda: False, 0.2)
    assert len(bench.board.applied_log) == applied and not bench.live()
    assert bench.node.health().level == 2
    assert bench.node.trigger_deactivate() == TransitionCallbackReturn.SUCCESS
    assert bench.node.trigger_activate() == TransitionCallbackReturn.SUCCESS
    assert bench.spin_until(bench.live)


def test_diagnostics_carry_the_link_figures(bench: Bench) -> None:
    bench.start()
    assert bench.spin_until(lambda: len(bench.bridge_statuses()) >= 2, 5.0)
    status = bench.bridge_statuses()[-1]
    values = {kv.key: kv.value for kv in status.values}
    for key in (
        "link_up",
        "packet_loss",
        "longest_loss_streak",
        "rtt_p50_ms",
        "rtt_p99_ms",
        "late_commands",
        "rejected_crc",
        "rejected_session",
        "fault_bits",
        "supply_pressure_bar",
    ):
        assert key in values
    assert values["link_up"] == "True" and float(values["supply_pressure_bar"]) == pytest.approx(
        10.0, abs=0.01
    )
    assert bench.internals, "no internals published"


@pytest.mark.parametrize("loop", LOOPS)
def test_counts_wider_than_the_counters_are_rejected_and_the_loop_keeps_running(
    ros_context: Any, loop: str
) -> None:
    from smm_hw_bridge.protocol import FeedbackFrame, encode

    bits, wide = 24, 5
    bench = Bench(ros_context, loop=loop, counter_bits=bits)
    try:
        bench.start()
        node, core = bench.node, bench.node.core
        reader = node._reader
        genuine = bench.board.last_feedback
        assert genuine is not None
        frame = encode(FeedbackFrame(**{**genuine.__dict__, "counts": (1 << bits, genuine.counts[1])}))
        for _ in range(wide):
            bench.emulator.transport.send(frame)  # from the board's own address and port
        answered = bench.measurements
        assert bench.spin_until(
            lambda: core.rejected.get(Reason.FIELD, 0) == wide and bench.measurements > answered + 10
        ), (core.rejected, bench.measurements, reader.is_alive())
        assert reader.is_alive() and node._reader is reader
        assert node.lifecycle_state == "active" and core.state == BridgeState.ARMED
        assert node.health().values["rejected_field"] == wide
        assert bench.spin_until(bench.live)

        def field_in_diagnostics() -> bool:
            statuses = bench.bridge_statuses()
            return bool(statuses) and {kv.key: kv.value for kv in statuses[-1].values}.get(
                "rejected_field"
            ) == str(wide)

        assert bench.spin_until(field_in_diagnostics, 5.0), "rejected_field not in /diagnostics"
    finally:
        bench.close()


@pytest.mark.parametrize("loop", LOOPS)
def test_an_exception_in_frame_handling_is_a_host_fault_and_the_reader_survives(
    ros_context: Any, loop: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn

    # neither the board's watchdog nor the host's can be the reason the valves go to null
    overrides = {"bridge.validity_ticks": 5000, "bridge.host_watchdog_ns": 5_000_000_000}
    bench = Bench(ros_context, loop=loop, **overrides)
    try:
        bench.start()
        node, core = bench.node, bench.node.core
        reader = node._reader
        handle = core.on_feedback
        calls: list[int] = []

        def raise_once(reading: Any, rx_ns: int) -> Any:
            calls.append(rx_ns)
            if len(calls) == 1:
                raise RuntimeError("injected bug in frame handling")
            return handle(reading, rx_ns)

        safe_before = node.counters.safe_frames_sent
        monkeypatch.setattr(core, "on_feedback", raise_once)
        # nothing spins: the reader thread alone must send the safe frame and keep reading
        deadline = time.monotonic() + 5.0
        while len(calls) < 20 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert len(calls) >= 20, "the reader stopped reading after the exception"
        assert reader.is_alive() and node._reader is reader
        assert node.counters.safe_frames_sent > safe_before and core.state == BridgeState.DISARMED
        health = node.health()
        assert health.level == 2 and "host fault" in health.message and "injected bug" in health.message
        assert_safe_now(bench)
        assert bench.spin_until(lambda: node.lifecycle_state == "unconfigured")  # the error transition
        assert not bench.live()
        assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS  # and it recovers
        assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert bench.spin_until(bench.live)
        assert node._reader is not None and node._reader.is_alive()
    finally:
        bench.close()


def raw_board(host_port: int, board_port: int, stop: threading.Event, bits: int, wide: int) -> None:
    """A board of one session sending feedback every 10 ms from ``board_port``, once the bridge has bound
    ``host_port``: the first ``wide`` frames count 2**bits (too wide for ``bits``-bit counters)."""
    from smm_hw_bridge.protocol import encode

    local = f"0100007F:{host_port:04X}"  # 127.0.0.1 as /proc/net/udp writes it
    while not stop.is_set():  # until configure has bound the bridge's port (so no frame is lost)
        with open("/proc/net/udp") as table:
            if any(line.split()[1] == local for line in list(table)[1:]):
                break
        time.sleep(0.005)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((LOOPBACK, board_port))
        seq = 0
        while not stop.is_set():
            seq += 1
            counts = (1 << bits, 0) if seq <= wide else ((1 << bits) - 1, 0)
            # a frame every 10 ms of the 1 kHz board clock
            frame = feedback_frame(0x1234, seq, 10 * seq, counts=counts)
            sock.sendto(encode(frame), (LOOPBACK, host_port))
            time.sleep(0.01)


class RawBench:
    """A bridge node (``bits``-bit counters) and :func:`raw_board` in a thread, started anew at each
    :meth:`configure`."""

    def __init__(self, context: Any, bits: int, wide: int) -> None:
        from smm_hw_bridge.bridge_node import HwBridgeNode

        self.bits, self.wide = bits, wide
        self.host_port, self.board_port = free_port(), free_port()
        self.node = HwBridgeNode(
            context=context,
            parameter_overrides={
                "link.bind_port": self.host_port,
                "link.board_port": self.board_port,
                "link.configure_timeout": 2.0,
                "bridge.encoder.counter_bits": bits,
                "bridge.admission.stale_ns": 1_000_000_000,  # a sender thread sharing this process's GIL
            },
        )
        self.stop = threading.Event()
        self.sender: threading.Thread | None = None

    def configure(self) -> Any:
        self.halt()
        self.stop.clear()
        arguments = (self.host_port, self.board_port, self.stop, self.bits, self.wide)
        self.sender = threading.Thread(target=raw_board, args=arguments, daemon=True)
        self.sender.start()
        return self.node.trigger_configure()

    def halt(self) -> None:
        self.stop.set()
        if self.sender is not None:
            self.sender.join(5.0)

    def close(self) -> None:
        self.halt()
        self.node.destroy_node()


def test_configure_rejects_counts_wider_than_the_counters_and_adopts_the_next_good_frame(
    ros_context: Any,
) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn

    bench = RawBench(ros_context, bits=24, wide=3)
    try:
        assert bench.configure() == TransitionCallbackReturn.SUCCESS
        core = bench.node.core
        assert core is not None and core.board_session == 0x1234
        assert dict(core.rejected) == {Reason.FIELD: 3}  # every wide frame, and nothing else
        assert core.last_feedback is not None and core.last_feedback.seq > 3
    finally:
        bench.close()


def test_an_exception_while_configure_waits_fails_it_and_frees_the_socket(
    ros_context: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn
    from smm_hw_bridge.core import BridgeCore

    bench = RawBench(ros_context, bits=24, wide=0)
    try:
        with monkeypatch.context() as patch:

            def broken(self: BridgeCore, reading: Any, rx_ns: int) -> None:
                raise RuntimeError("injected bug in frame handling")

            patch.setattr(BridgeCore, "on_feedback", broken)
            assert bench.configure() == TransitionCallbackReturn.FAILURE
        assert bench.node.lifecycle_state == "unconfigured" and bench.node.device is None
        assert bench.configure() == TransitionCallbackReturn.SUCCESS  # its port was closed: bound again
    finally:
        bench.close()


@pytest.mark.parametrize("loop", LOOPS)
def test_fuzz_10000_frames_into_the_running_bridge_socket(ros_context: Any, loop: str) -> None:
    # the emulator shares this process's GIL with the fuzzer: a generous link timeout keeps a starved
    # emulator thread from looking like a lost link (which would rightly disarm the bridge)
    # Lockstep emulator: a feedback frame only after the command answering the last one, so the board's own
    # traffic never fills the bridge's socket buffer while this process's threads wait for the GIL (in real
    # time the kernel then dropped fuzz frames before the parser saw them).
    bench = Bench(
        ros_context,
        mode="lockstep",
        loop=loop,
        **{"bridge.link_timeout_ns": 5_000_000_000, "bridge.admission.stale_ns": 5_000_000_000},
    )
    try:
        fuzz(bench)
    finally:
        bench.close()


def fuzz_frames(genuine: Any) -> list[bytes]:
    """10,400 frames the bridge must reject: random and one-byte-mutated ones (hypothesis), foreign sessions,
    another protocol version (valid CRC)."""
    from smm_hw_bridge.protocol import FeedbackFrame, encode

    template = encode(genuine)
    frames: list[bytes] = []

    @settings(
        max_examples=10_000,
        deadline=None,
        database=None,
        derandomize=True,
        suppress_health_check=list(HealthCheck),
    )
    @given(st.one_of(st.binary(max_size=100), st.tuples(st.integers(0, 71), st.integers(1, 255))))
    def collect(case: bytes | tuple[int, int]) -> None:
        if isinstance(case, bytes):
            frames.append(case if case[:4] != b"SMMB" else b"X" + case)  # random bytes: never a frame
        else:
            index, flip = case
            data = bytearray(template)
            data[index] ^= flip  # one byte changed, CRC not fixed: always rejected
            frames.append(bytes(data))

    collect()
    for index in range(200):  # valid CRC: foreign sessions (all different), another protocol version
        frames.append(encode(FeedbackFrame(**{**genuine.__dict__, "session": 0x1000 + index})))
        body = template[:4] + b"\x02" + template[5:-4]
        frames.append(body + zlib.crc32(body).to_bytes(4, "little"))
    assert len(frames) >= 10_000
    return frames


def fuzz(bench: Bench) -> None:
    # The frames are made before the output is armed: making them takes seconds in which nothing spins
    # the executor, and an armed lockstep loop nobody answers rightly loses its link.
    assert bench.spin_until(lambda: bench.board.last_feedback is not None)
    genuine = bench.board.last_feedback
    assert genuine is not None
    frames = fuzz_frames(genuine)
    bench.start()
    core = bench.node.core
    before = parse_and_session_rejections(core)

    sender = bench.emulator.transport  # from the board's own address and port
    for start in range(0, len(frames), 20):  # small batches: the socket buffer never overflows
        batch = frames[start : start + 20]
        for data in batch:
            while True:  # the socket is non-blocking: a full send buffer is counted, not raised; retry
                dropped = sender.dropped.get("send", 0)
                sender.send(data)
                if sender.dropped.get("send", 0) == dropped:
                    break
                time.sleep(0.001)
        target = before + start + len(batch)
        answered = bench.measurements
        # Every batch is rejected and the control loop answers a new measurement meanwhile: the fuzz runs
        # into a live loop. (Waiting for the rejections alone spun nothing, as the bridge reads in its own
        # thread: the lockstep board starved and the bridge rightly lost the link after link_timeout.)
        assert bench.spin_until(
            lambda t=target, m=answered: parse_and_session_rejections(core) >= t and bench.measurements > m,
            10.0,
        ), (core.state, bench.measurements, core.watchdog_trips)
    counted = {r.value: core.rejected.get(r, 0) for r in PARSE_AND_SESSION_REASONS}
    print(f"fuzz: {len(frames)} frames into the running bridge, rejected by reason: {counted}")
    assert sum(counted.values()) - before == len(frames)
    assert bench.node.lifecycle_state == "active", core.state  # the node keeps running
    values = bench.node.health().values
    for reason in ("crc", "magic", "length", "version", "session"):
        assert int(values[f"rejected_{reason}"]) > 0, reason  # type: ignore[call-overload]
    assert bench.spin_until(bench.live), (core.state, bench.measurements)
    assert bench.measurements > len(frames) // 20  # at least one control step per batch
