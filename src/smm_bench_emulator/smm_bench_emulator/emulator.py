"""The emulator process's loop: the board core on UDP, clocked by its own 1 kHz timer or in lockstep.

Fault requests arrive as JSON datagrams on a control port (loopback) and are answered with JSON:
``{"fault": "drop", "count": 5}``, ``{"fault": "delay", "count": 50, "ticks": 30}``, ``{"reboot": true}``,
``{"faults": 2}``, ``{"supply": 3.0}``, ``{"clear": true}``, ``{"status": true}``, ``{"stop": true}``.
"""

from __future__ import annotations

import json
import select
import socket
import time
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from typing import Any, Literal

from smm_hw_bridge.control_rate import MAX_DIVIDER, is_control_tick
from smm_hw_bridge.protocol import encode
from smm_hw_bridge.run_verdict import RunTally, VerdictConfig
from smm_hw_bridge.transport import Transport, UdpTransport
from smm_schema.ranges import at_least, bounds, check_bounds, no_range

from smm_bench_emulator.board import BoardConfig, BoardCore
from smm_bench_emulator.faults import LinkFault, LinkFaults
from smm_bench_emulator.latency import LatencyHistogram

__all__ = ["Emulator", "EmulatorConfig"]

Mode = Literal["realtime", "lockstep"]


@dataclass(frozen=True)
class EmulatorConfig:
    """Where the emulator listens and how it is clocked.

    Attributes:
        board: The emulated bench.
        bind: (address, port) the board's UDP socket binds.
        host: (address, port) of the bridge: feedback goes there, commands are accepted from there only.
        control: (address, port) of the JSON control socket, or None for none.
        mode: ``realtime`` (own 1 kHz timer) or ``lockstep`` (a tick when the last feedback is answered).
        lockstep_trigger: ``any``: any valid command answering the last feedback ticks the board;
            ``enabled``: only an enabled one (the plant waits at tick 0 until the controller drives it, so a
            run lines up with the simulator's from its first step).
        resend_ns: Lockstep: re-send the unanswered feedback after this long (ns), > 0.
        duration_ticks: Stop after this many ticks (0 = run until stopped), counted from boot, or with
            ``duration_from_live`` from the first tick that latched an enabled command.
        duration_from_live: Count ``duration_ticks`` from the first live tick (live or not since): a host
            slow to start (a loaded machine) shortens no run.
        seed: Seed of the injected corruption.
        verdict: When the run counts as controlled (:mod:`smm_hw_bridge.run_verdict`).
        start_timeout_ns: Stop, as a run that never started, when no tick came (lockstep) or no tick
            latched an enabled command (realtime) this long (ns) after boot (0 = wait for ever).
        control_divider: N, board ticks per control period (the bridge's ``bridge.control_divider``): the
            run is judged per period, and in lockstep only control ticks (multiples of N) wait for the
            host; the others hold its command, as the board does in real time.
        min_idle_ns: Realtime: after a tick the loop waits at least this long (ns) before the next, even
            when behind; on a shared host a board behind its clock must not take the CPU from the host's
            threads, as a separate board never would (docs/LAUNCH.md, "Real time").
    """

    board: BoardConfig = field(default_factory=BoardConfig)
    bind: tuple[str, int] = ("127.0.0.1", 50101)
    host: tuple[str, int] = ("127.0.0.1", 50100)
    control: tuple[str, int] | None = ("127.0.0.1", 50102)
    mode: Mode = "realtime"
    lockstep_trigger: Literal["any", "enabled"] = "any"
    resend_ns: int = field(default=50_000_000, metadata=at_least(1))
    duration_ticks: int = field(default=0, metadata=at_least(0))
    duration_from_live: bool = False
    seed: int = field(default=0, metadata=no_range())
    verdict: VerdictConfig = field(default_factory=VerdictConfig)
    start_timeout_ns: int = field(default=0, metadata=at_least(0))
    min_idle_ns: int = field(default=100_000, metadata=at_least(0))
    control_divider: int = field(default=1, metadata=bounds(1, MAX_DIVIDER))

    def __post_init__(self) -> None:
        if self.lockstep_trigger not in ("any", "enabled"):
            raise ValueError(f"lockstep_trigger must be 'any' or 'enabled', got {self.lockstep_trigger!r}")
        if self.mode not in ("realtime", "lockstep"):
            raise ValueError(f"mode must be 'realtime' or 'lockstep', got {self.mode!r}")
        check_bounds(self)


class Emulator:
    """Runs a :class:`BoardCore` against a UDP transport until stopped.

    Args:
        config: Addresses, clock mode and the bench.
        transport: Link to the bridge (default: UDP on ``config.bind`` to ``config.host``).
        clock_ns: Monotonic clock (ns).
        record: Keep the per-tick record (:attr:`record`).
        wall_ns: The clock of the transport's kernel arrival times (CLOCK_REALTIME, ns).
    """

    def __init__(
        self,
        config: EmulatorConfig,
        transport: Transport | None = None,
        clock_ns: Callable[[], int] = time.monotonic_ns,
        record: bool = False,
        wall_ns: Callable[[], int] = time.time_ns,
    ) -> None:
        self.config = config
        self.board = BoardCore(config.board)
        self.faults = LinkFaults(config.seed)
        self.transport = (
            transport
            if transport is not None
            else UdpTransport(config.bind, config.host, kernel_timestamps=True)
        )
        self._control: socket.socket | None = None
        if config.control is not None:
            self._control = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._control.bind(config.control)
            self._control.setblocking(False)
        self._clock = clock_ns
        self._wall = wall_ns
        self.running = False
        self.overruns = 0
        self.ticks = 0
        self.null_since_ns: int | None = None
        self._sent_ns: dict[int, tuple[int, int]] = {}
        self.latencies = LatencyHistogram()
        """Feedback sent -> enabled command answering it arrived, one per answered feedback: the kernel's
        arrival time where the transport gives it, else when this process read it (bounded memory)."""
        self.read_latencies = LatencyHistogram()
        """Feedback sent -> enabled command answering it read by this process (ns): also this process's
        own wake-up, which a board's receive interrupt does not have."""
        self.record: list[tuple[int, float, float, int, int]] | None = [] if record else None
        """Per tick: (tick, true alpha, true beta (rad), D/A codes), when ``record`` is set."""
        self.null_since_tick: int | None = None
        self.last_command_ns: int | None = None
        self.last_enabled_ns: int | None = None
        self.tally = RunTally(config.board.period_ns, config.verdict, config.control_divider)
        """Enabled and late ticks of the feedback sent, as the bridge counts them."""
        self._live_from: int | None = None
        self.never_started = False
        """Lockstep: no tick within ``start_timeout_ns``."""

    @property
    def control_address(self) -> tuple[str, int] | None:
        """Bound (address, port) of the control socket."""
        return None if self._control is None else self._control.getsockname()[:2]

    def close(self) -> None:
        """Closes the sockets."""
        self.transport.close()
        if self._control is not None:
            self._control.close()

    def _send(self, frame: bytes) -> None:
        now = self._clock()  # before the send: a host may answer before this process runs again
        wall = self._wall()
        for data in self.faults.outgoing(frame, self.board.tick):
            self.transport.send(data)
        feedback = self.board.last_feedback
        if feedback is not None:
            self.tally.on_feedback(feedback)
            self._sent_ns[feedback.seq] = (now, wall)
            if len(self._sent_ns) > 2000:
                del self._sent_ns[next(iter(self._sent_ns))]
            if self.record is not None:
                alpha, beta, _, _ = self.board.plant.state_floats
                self.record.append((feedback.tick, alpha, beta, *self.board.output_codes()))
        if self.board.output_codes() == (0, 0):
            if self.null_since_ns is None:
                self.null_since_ns, self.null_since_tick = now, self.board.tick
        else:
            self.null_since_ns = self.null_since_tick = None
        self.ticks += 1
        if self._live_from is None and self.tally.live_ticks:
            self._live_from = self.ticks - 1
        counted = self.ticks
        if self.config.duration_from_live:
            counted = 0 if self._live_from is None else self.ticks - self._live_from
        if self.config.duration_ticks and counted >= self.config.duration_ticks:
            self.running = False

    def _drain(self, readable: Collection[int] | None = None) -> None:
        """Reads what waits on the ``readable`` descriptors (:meth:`_wait`'s), or on both sockets (None)."""
        if readable is not None and not readable:
            return
        if readable is None or self.transport.fileno() in readable:
            self._read_frames()
        if self._control is not None and (readable is None or self._control.fileno() in readable):
            self._read_requests()

    def _read_frames(self) -> None:
        while (data := self.transport.receive(0.0)) is not None:
            arrived = self._clock()  # before the board parses it: a real board's parse takes microseconds
            stamp = self.transport.last_stamp_ns
            passed = self.faults.incoming(data)
            if passed is not None:
                command = self.board.receive(passed)
                if command is not None:
                    self.last_command_ns = arrived
                    sent = self._sent_ns.pop(command.answers_seq, None)
                    if sent is not None and command.enabled:
                        self.read_latencies.add(arrived - sent[0])
                        self.latencies.add(arrived - sent[0] if stamp is None else stamp - sent[1])
                    if command.enabled:
                        self.last_enabled_ns = self.last_command_ns
                        self.tally.armed = True

    def _read_requests(self) -> None:
        assert self._control is not None
        while True:
            try:
                request, source = self._control.recvfrom(4096)
            except BlockingIOError:
                break
            reply = self.handle(request)
            self._control.sendto(json.dumps(reply).encode(), source)

    def handle(self, request: bytes) -> dict[str, Any]:
        """Carries out one JSON control request and returns the reply."""
        try:
            message = json.loads(request)
            if not isinstance(message, dict):
                raise ValueError("a request is a JSON object")
            if "fault" in message:
                self.faults.request(
                    LinkFault(message["fault"]), int(message.get("count", 1)), int(message.get("ticks", 0))
                )
            elif message.get("reboot"):
                self.board.boot()
                self.transport.send(self.board.start())
            elif "faults" in message:
                self.board.set_faults(int(message["faults"]))
            elif "supply" in message:
                self.board.supply_pressure = float(message["supply"])
            elif message.get("clear"):
                self.faults.clear()
            elif message.get("stop"):
                self.running = False
            elif not message.get("status"):
                raise ValueError(f"unknown request {message!r}")
        except (ValueError, TypeError, KeyError) as error:
            return {"ok": False, "error": str(error)}
        return {"ok": True, **self.status()}

    def status(self) -> dict[str, Any]:
        """Board state for the control socket and the end-of-run summary."""
        board = self.board
        return {
            "session": board.session,
            "tick": board.tick,
            "output_codes": list(board.output_codes()),
            "estop": board.estop_latched,
            "faults": board.faults,
            "host_session": board.host_session,
            "late_commands": board.late_commands,
            "enabled_ticks": board.enabled_ticks,
            "crc_errors": board.crc_errors,
            "dropped_frames": board.dropped_frames,
            "overruns": self.overruns,
            "ticks": self.ticks,
            "null_since_ns": self.null_since_ns,
            "null_since_tick": self.null_since_tick,
            "last_command_ns": self.last_command_ns,
            "last_enabled_ns": self.last_enabled_ns,
            "applied": len(board.applied_log),
            "latency_p50_us": self.latencies.percentile_us(50),
            "latency_p99_us": self.latencies.percentile_us(99),
            "read_latency_p50_us": self.read_latencies.percentile_us(50),
            "read_latency_p99_us": self.read_latencies.percentile_us(99),
            "last_applied_tick": board.applied_log[-1][0] if board.applied_log else None,
            "status_bits": 0 if board.last_feedback is None else board.last_feedback.status,
            "armed": self.tally.armed,
            "live_ticks": self.tally.live_ticks,
            "control_divider": self.config.control_divider,
            "judged_periods": self.tally.periods,
            "late_periods": self.tally.late_periods,
            "settle_s": self.config.verdict.settle_s,
            "late_limit": self.config.verdict.late_limit,
            "figures": self.tally.figures(),
            "verdict": self.verdict(),
        }

    def verdict(self) -> str | None:
        """Why the run did not control, or None if it did (:meth:`RunTally.verdict`)."""
        if self.never_started:
            timeout = self.config.start_timeout_ns / 1e9
            if self.config.mode == "realtime":
                return f"the bridge never armed: no tick latched an enabled command within {timeout:g} s"
            return f"the lockstep run never started: no step within its start timeout of {timeout:g} s"
        return self.tally.verdict()

    def _wait(self, timeout_ns: int) -> list[int]:
        """Sleeps until a socket is readable or ``timeout_ns`` (ns) passed; the readable descriptors."""
        sources = [self.transport.fileno()] + ([self._control.fileno()] if self._control is not None else [])
        readable: list[int] = select.select(sources, [], [], max(timeout_ns, 0) / 1e9)[0]
        return readable

    def run(self) -> None:
        """Runs until ``stop`` is requested or ``duration_ticks`` have passed."""
        self.running = True
        self._send(self.board.start())
        if self.config.mode == "realtime":
            self._run_realtime()
        else:
            self._run_lockstep()

    def _run_realtime(self) -> None:
        period = self.config.board.period_ns
        deadline = started = self._clock() + period
        timeout = self.config.start_timeout_ns
        while self.running:
            now = self._clock()
            if timeout and not self.tally.live_ticks and now - started > timeout:
                self.never_started, self.running = True, False
                break
            if now < deadline:  # asleep to the tick's deadline; a datagram is read when it comes
                self._drain(self._wait(deadline - now))
                continue  # the last wait timed out with nothing to read: tick now, no read before it
            self._send(self.board.tick_realtime())
            deadline += period
            now = self._clock()
            if now > deadline:
                self.overruns += 1  # the ticks still run, the board's clock is the plant's, but never
                self._drain(self._wait(self.config.min_idle_ns))  # back to back: the host needs the CPU

    def _run_lockstep(self) -> None:
        resend = self.config.resend_ns
        sent = started = self._clock()
        timeout = self.config.start_timeout_ns
        while self.running:
            if timeout and self.ticks <= 1 and self._clock() - started > timeout:
                self.never_started, self.running = True, False
                break
            # a tick between two control ticks waits for no one: the board holds the host's command
            holding = not is_control_tick(self.board.tick, self.config.control_divider)
            if not holding:
                self._wait(resend - (self._clock() - sent))
            self._drain()
            enabled_only = self.config.lockstep_trigger == "enabled"
            if holding or (self.board.answered_enabled if enabled_only else self.board.answered):
                self._send(self.board.tick_lockstep())
                sent = self._clock()
            elif self._clock() - sent >= resend and self.board.last_feedback is not None:
                self.transport.send(encode(self.board.last_feedback))
                sent = self._clock()
