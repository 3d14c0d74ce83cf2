"""The emulator process loop over loopback UDP: lockstep and 1 kHz clocking, control port, injected faults."""

from __future__ import annotations

import json
import math
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from smm_bench_emulator.board import BoardConfig
from smm_bench_emulator.cli import main as emulator_main
from smm_bench_emulator.emulator import Emulator, EmulatorConfig
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeState
from smm_hw_bridge.encoder import EncoderConfig
from smm_hw_bridge.protocol import CommandFlag, CommandFrame, Reason, encode
from smm_hw_bridge.run_verdict import EXIT_NOT_CONTROLLED
from smm_hw_bridge.transport import UdpTransport
from smm_hw_bridge.valve_output import ValveOutputConfig
from smm_sim.plant import PlantConfig
from udp_bench import LOOPBACK, parse_and_session_rejections

CPR = 1 << 16
BRIDGE = BridgeConfig(
    encoder=EncoderConfig(counts_per_rev=(CPR, CPR)),
    valve=ValveOutputConfig(rate_limit=(math.inf, math.inf)),
    link_timeout_ns=2_000_000_000,
    admission=BridgeConfig().admission.__class__(stale_ns=2_000_000_000),
)


@contextmanager
def emulator(mode: str, **board: object) -> Iterator[tuple[Emulator, UdpTransport]]:
    host = UdpTransport((LOOPBACK, 0), (LOOPBACK, 9))
    config = EmulatorConfig(
        board=BoardConfig(plant=PlantConfig(encoder_counts_per_rev=CPR), adc_noise=0.0, **board),  # type: ignore[arg-type]
        bind=(LOOPBACK, 0),
        host=host.local_address,
        control=(LOOPBACK, 0),
        mode=mode,  # type: ignore[arg-type]
        resend_ns=20_000_000,
    )
    emu = Emulator(config)
    host.set_peer(emu.transport.local_address)  # type: ignore[attr-defined]
    thread = threading.Thread(target=emu.run, daemon=True)
    thread.start()
    try:
        yield emu, host
    finally:
        emu.running = False
        thread.join(5.0)
        emu.close()
        host.close()


def control(emu: Emulator, request: dict[str, object]) -> dict[str, object]:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(5.0)
        sock.sendto(json.dumps(request).encode(), emu.control_address)  # type: ignore[arg-type]
        reply: dict[str, object] = json.loads(sock.recv(65536))
        return reply


def drive(
    core: BridgeCore, host: UdpTransport, frames: int, torque: tuple[float, float] = (0.3, -0.2)
) -> None:
    """Answers ``frames`` admitted feedback frames: a safe frame until armed, then a torque command."""
    answered = 0
    deadline = time.monotonic() + 30.0
    while answered < frames and time.monotonic() < deadline:
        data = host.receive(0.1)
        if data is None:
            continue
        now = time.monotonic_ns()
        if core.on_datagram(data, now) is None:
            continue
        if core.state in (BridgeState.ARMING, BridgeState.ARMED):
            core.on_command(torque, core.stamp_ns, now)
        frame = core.next_frame(now)
        if frame is not None:
            host.send(encode(frame))
        answered += 1
    assert answered == frames, f"only {answered} of {frames} feedback frames answered"


def test_lockstep_over_udp_applies_every_command_and_counts_no_late_one() -> None:
    with emulator("lockstep") as (emu, host):
        core = BridgeCore(BRIDGE, host_session=0x42)
        drive(core, host, 3)
        core.arm()
        drive(core, host, 200)
        status = control(emu, {"status": True})
        assert core.state == BridgeState.ARMED
        assert status["late_commands"] == 0 and status["output_codes"] == [983, -655]
        assert status["applied"] >= 195  # type: ignore[operator]
        assert emu.board.tick >= 200


def test_injected_faults_are_seen_and_counted_by_the_bridge() -> None:
    with emulator("lockstep") as (emu, host):
        core = BridgeCore(BRIDGE, host_session=0x43)
        drive(core, host, 3)
        core.arm()
        drive(core, host, 20)
        for request in (
            {"fault": "corrupt", "count": 5},
            {"fault": "duplicate", "count": 4},
            {"fault": "reorder", "count": 3},
        ):
            assert control(emu, request)["ok"] is True
            drive(core, host, 30)
        parse_errors = parse_and_session_rejections(core)
        assert parse_errors >= 5  # corrupted frames (and the lockstep re-sends after them)
        assert core.rejected.get(Reason.DUPLICATE, 0) >= 4
        assert core.rejected.get(Reason.OUT_OF_ORDER, 0) >= 1
        assert core.state == BridgeState.ARMED
        assert control(emu, {"bogus": 1})["ok"] is False


def test_reboot_over_udp_disables_output_until_rearmed() -> None:
    with emulator("lockstep") as (emu, host):
        core = BridgeCore(BRIDGE, host_session=0x44)
        drive(core, host, 3)
        core.arm()
        drive(core, host, 20)
        old_session = emu.board.session
        assert control(emu, {"reboot": True})["session"] != old_session
        applied = len(emu.board.applied_log)  # read after the reboot: a last answer may land just before it
        drive(core, host, 10)
        assert core.state == BridgeState.SESSION_LOST and core.reboots == 1
        assert len(emu.board.applied_log) == applied and emu.board.output_codes() == (0, 0)
        core.arm()
        drive(core, host, 10)
        assert core.state == BridgeState.ARMED
        assert len(emu.board.applied_log) > applied


@pytest.mark.realtime  # the test's host must keep up with 1 kHz; twin: test_board.py's hold-then-null
def test_realtime_board_clock_holds_then_nulls_when_the_host_goes_quiet() -> None:
    with emulator("realtime") as (emu, host):
        core = BridgeCore(BRIDGE, host_session=0x45)
        drive(core, host, 3)
        core.arm()
        drive(core, host, 200)
        assert core.state == BridgeState.ARMED
        # judged on the board's log, not on its output now: a test thread preempted for longer than the
        # validity would find the valves already nulled by the watchdog under test
        assert any(codes != (0, 0) for _, _, codes in emu.board.applied_log)
        deadline = time.monotonic() + 10.0
        while emu.board.output_codes() != (0, 0) and time.monotonic() < deadline:
            time.sleep(0.005)
        # board clock: the valves are at null by the board's own watchdog within the validity of the last
        # applied command (it answered a tick before the one it was latched at)
        assert emu.board.output_codes() == (0, 0)
        last = emu.board.applied_log[-1][0]
        assert emu.null_since_tick is not None
        assert 1 <= emu.null_since_tick - last <= BRIDGE.validity_ticks
        status = control(emu, {"status": True})
        assert status["ticks"] >= 200  # type: ignore[operator]


def test_cli_rejects_a_bad_address_with_exit_code_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert emulator_main(["--bind", "not-an-ip:1", "--control", "127.0.0.1:0", "--duration", "0.01"]) == 2
    assert "smm_bench_emulator" in capsys.readouterr().err


def test_cli_runs_for_its_duration_prints_a_summary_and_a_run_no_host_armed_exits_3(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = emulator_main(
        ["--bind", "127.0.0.1:0", "--host", "127.0.0.1:9", "--control", "127.0.0.1:0", "--duration", "0.05"]
    )
    assert code == EXIT_NOT_CONTROLLED
    out = capsys.readouterr()
    summary = json.loads(out.out.strip().splitlines()[-1])
    assert summary["ticks"] == 50 and summary["output_codes"] == [0, 0]
    assert summary["verdict"] == "the bridge never armed: no enabled command reached the board"
    assert "the run did not control: the bridge never armed" in out.err


def test_a_lockstep_run_without_a_first_step_within_its_start_timeout_never_started_and_exits_3(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = emulator_main(
        ["--bind", "127.0.0.1:0", "--host", "127.0.0.1:9", "--control", "127.0.0.1:0", "--mode", "lockstep",
         "--duration", "1", "--start-timeout", "0.2"]
    )  # fmt: skip
    assert code == EXIT_NOT_CONTROLLED
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["ticks"] == 1  # only the boot feedback
    assert summary["verdict"].startswith("the lockstep run never started: no step within its start timeout")


def _answered_emulator(now: list[int], wall: list[int]) -> tuple[Emulator, UdpTransport, CommandFrame]:
    """An emulator on the given clocks that sent its first feedback, and an enabled command answering it."""
    host = UdpTransport((LOOPBACK, 0), (LOOPBACK, 9))
    config = EmulatorConfig(
        board=BoardConfig(plant=PlantConfig(encoder_counts_per_rev=CPR), adc_noise=0.0),
        bind=(LOOPBACK, 0),
        host=host.local_address,
        mode="realtime",
    )
    emu = Emulator(config, clock_ns=lambda: now[0], wall_ns=lambda: wall[0])
    emu._send(emu.board.start())
    feedback = emu.board.last_feedback
    assert feedback is not None
    command = CommandFrame(
        7, 1, feedback.session, feedback.seq, feedback.tick, CommandFlag.ENABLE, 10, (5, 5)
    )
    return emu, host, command


def test_latency_runs_from_the_feedback_leaving_to_the_command_arriving_not_to_the_end_of_its_parse() -> None:
    """The emulator's own (Python) parse time is not the host's: the arrival is timed before it."""
    now = [1_000_000]  # the feedback leaves at 1 ms
    emu, host, command = _answered_emulator(now, [5_000_000_000])
    try:
        arrival = 1_250_000
        received = iter([encode(command)])
        emu.transport.receive = lambda timeout_s=0.0: next(received, None)  # type: ignore[method-assign]

        def slow_parse(data: bytes) -> CommandFrame:
            now[0] += 400_000  # the board's parse takes 0.4 ms
            return command

        emu.board.receive = slow_parse  # type: ignore[method-assign]
        now[0] = arrival
        emu._drain()
        # this transport gives no kernel arrival time: both are the read time
        assert emu.latencies.count == emu.read_latencies.count == 1
        assert emu.latencies.percentile_us(50) == emu.read_latencies.percentile_us(50) == 250.0
        assert emu.last_command_ns == arrival
    finally:
        emu.close()
        host.close()


def test_latency_takes_the_kernel_arrival_time_where_the_transport_gives_it() -> None:
    """Arrival by the socket's kernel timestamp; the process's own wake-up is the read latency only."""
    now, wall = [1_000_000], [5_000_000_000]  # leaves at monotonic 1 ms, wall 5 s
    emu, host, command = _answered_emulator(now, wall)
    try:
        received = iter([encode(command)])

        def receive(timeout_s: float = 0.0) -> bytes | None:
            data = next(received, None)
            emu.transport.last_stamp_ns = None if data is None else wall[0] + 180_000
            return data

        emu.transport.receive = receive  # type: ignore[method-assign]
        emu.board.receive = lambda data: command  # type: ignore[method-assign]
        now[0] += 700_000  # the emulator process read it 0.7 ms after it left
        emu._drain()
        assert (emu.latencies.count, emu.latencies.percentile_us(50)) == (1, 180.0)
        assert (emu.read_latencies.count, emu.read_latencies.percentile_us(50)) == (1, 700.0)
        status = emu.status()
        assert status["latency_p99_us"] == 180.0 and status["read_latency_p99_us"] == 700.0
    finally:
        emu.close()
        host.close()


def test_a_realtime_run_counted_from_live_output_that_never_arms_stops_at_its_start_timeout(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = emulator_main(
        ["--bind", "127.0.0.1:0", "--host", "127.0.0.1:9", "--control", "127.0.0.1:0", "--duration", "0.01",
         "--duration-from", "live", "--start-timeout", "0.3"]
    )  # fmt: skip
    assert code == EXIT_NOT_CONTROLLED
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["ticks"] > 10  # 10 ticks of board time passed, but none was live: the run goes on
    assert summary["verdict"] == "the bridge never armed: no tick latched an enabled command within 0.3 s"


def test_the_realtime_loop_reads_only_the_socket_its_wait_found_readable() -> None:
    """A control request is answered when its socket is readable, not at a wake-up for a command frame."""
    emu = Emulator(
        EmulatorConfig(
            board=BoardConfig(plant=PlantConfig(encoder_counts_per_rev=CPR), adc_noise=0.0),
            bind=(LOOPBACK, 0),
            host=(LOOPBACK, 9),
            control=(LOOPBACK, 0),
        )
    )
    frames: list[bytes] = []
    emu.transport.receive = lambda timeout_s=0.0: frames.pop() if frames else None  # type: ignore[method-assign]
    try:
        assert emu._wait(0) == []  # nothing to read: no wait, no read
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as client:
            client.settimeout(5.0)
            client.sendto(json.dumps({"status": True}).encode(), emu.control_address)  # type: ignore[arg-type]
            frames.append(b"a junk frame")
            emu._drain([emu.transport.fileno()])  # the frame's socket only
            assert frames == []
            readable = emu._wait(5_000_000_000)
            assert readable == [emu._control.fileno()]  # type: ignore[union-attr]
            emu._drain(readable)
            assert json.loads(client.recv(65536))["ok"] is True
    finally:
        emu.close()
