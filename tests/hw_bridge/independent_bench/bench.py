"""A second CANopen bench, written from the CiA 301 / 406 / 408 object lists alone (no smm_bench_emulator).

Two valves (nodes 21, 22) and two encoders (31, 32) as ``canopen`` LocalNodes with this folder's EDS files
(other PDO orders than the emulator's, device types with the high word set), and a plant of its own: the
SPEC's 2-DOF dynamics (M(q) of its Appendix A, C by Christoffel symbols of M by central differences,
gravity, viscous friction, case 2's disturbance and +10 % inertias), ideal valves (+-``FULL_SCALE_NM`` at
+-16384, no lag), encoders of ``COUNTS_PER_REV`` with their own zero and direction. Each SYNC:
the last RPDO latched, the plant moved at 1 kHz sub-steps over what passed since the last SYNC, the TPDOs
sent. What passed: on ``clock="sync"`` the cycle period the master wrote (0x1006) times the periods the
SYNC counter says passed (one without a counter: lockstep); on ``clock="wall"`` the wall clock's time.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import Final

import can
import canopen
import numpy as np

HERE = Path(__file__).resolve().parent
VALVE_NODES: Final = (21, 22)
ENCODER_NODES: Final = (31, 32)
FULL_SCALE_NM: Final = (12.0, 12.0)
COUNTS_PER_REV: Final = (1 << 19, 1 << 19)
ZERO_COUNTS: Final = (100_000, 7)
DIRECTION: Final = (1, -1)
SUPPLY_UNITS: Final = 1000
"""0x6381:01 at 10 bar (0.01 bar a unit)."""
_D, _H, _M, _R = 0x1, 0x2, 0x4, 0x8
_FAULT_DISABLED = 0b0001
_EMCY_RPDO_TIMEOUT = 0x8250
_STEP_S = 0.001
_STEP_NS = 1_000_000
_COUNTER_OVERFLOW = 240
"""The SYNC counter runs 1 .. this (CiA 301 0x1019's highest value, the one the master uses)."""
CLOCKS: Final = ("sync", "wall")
_Pair = tuple[float, float]


class Valve:
    """CiA 408 device state machine: status R M H D; D, H, M cumulative; R's rising edge resets a fault."""

    def __init__(self) -> None:
        self.status = 0b1000  # INIT
        self.control = 0
        self.setpoint = 0
        self.spool = 0.0
        """The spool opening (fraction of full scale)."""

    @property
    def faulted(self) -> bool:
        return not self.status & _R and self.status != 0

    def take(self, word: int, setpoint: int) -> None:
        rising = bool(word & _R and not self.control & _R)
        self.control = word
        self.setpoint = max(-16384, min(16384, setpoint))
        if self.faulted:
            if rising:
                self.status = 0b1001 if word & _D else 0b1000
            return
        if not word & _D:
            self.status = 0b1000
        elif not word & _H:
            self.status = 0b1001
        else:
            self.status = 0b1111 if word & _M else 0b1011

    @property
    def active(self) -> bool:
        return self.status == 0b1111

    def demand(self) -> float:
        """The spool demand now (fraction): the bus setpoint when ACTIVE, else null."""
        return self.setpoint / 16384.0 if self.active else 0.0


class Plant:
    """The SMM's 2-DOF dynamics (SPEC section 1) with case 2's disturbance and inertias +10 %, RK4."""

    def __init__(self, seed: int = 5) -> None:
        parallel = 3.9 * 0.005**2 + 1.2 * 0.0035**2 + 5.4 * 0.003**2
        scale = 1.1
        self.i11 = self.i22 = self.i44 = scale * (0.069 + parallel)
        self.i55 = scale * 0.071
        self.mgl = 0.0399 * 9.81
        self.friction = 0.1
        self.q = np.zeros(2)
        self.v = np.zeros(2)
        self.t = 0.0
        self.noise = np.random.default_rng(seed)

    def mass(self, a: float, b: float) -> tuple[float, float, float]:
        """M(q)'s entries m11, m12, m22 at q = (a, b) (SPEC Appendix A)."""
        tan_a, cos_b, sin_b = math.tan(a), math.cos(b), math.sin(b)
        sec2 = 1.0 / math.cos(a) ** 2
        d = tan_a**2 + cos_b**2
        m11 = self.i44 + sec2 * cos_b**2 / d**2 * (self.i55 * sec2 - self.i11 * d)
        m12 = tan_a * sin_b * cos_b / d**2 * (self.i55 * sec2 - 0.5 * self.i11 * d)
        m22 = self.i22 + self.i55 * tan_a**2 * sin_b**2 / d**2
        return m11, m12, m22

    def _accel(self, q: _Pair, v: _Pair, tau: _Pair, t: float) -> _Pair:
        """q'' from M q'' = tau - C(q, q') q' - g(q) - friction q' - disturbance (floats: a SYNC's budget)."""
        a, b = q
        h = 1e-6
        # dM/dq_i by central differences, each as a 2x2 (row, column) of floats
        dm = []
        for plus, minus in (
            (self.mass(a + h, b), self.mass(a - h, b)),
            (self.mass(a, b + h), self.mass(a, b - h)),
        ):
            d11, d12, d22 = ((p - m) / (2 * h) for p, m in zip(plus, minus, strict=True))
            dm.append(((d11, d12), (d12, d22)))
        coriolis = [
            sum(
                0.5 * (dm[i][k][j] + dm[j][k][i] - dm[k][i][j]) * v[i] * v[j]
                for i in range(2)
                for j in range(2)
            )
            for k in range(2)
        ]
        gravity = (0.0, -self.mgl * math.sin(b))
        wave = 0.5 * math.cos(7 * t) if t > 1.0 else 0.0
        disturbance = (-wave, wave)
        rhs = [tau[k] - coriolis[k] - gravity[k] - self.friction * v[k] - disturbance[k] for k in range(2)]
        m11, m12, m22 = self.mass(a, b)
        det = m11 * m22 - m12 * m12
        return (m22 * rhs[0] - m12 * rhs[1]) / det, (m11 * rhs[1] - m12 * rhs[0]) / det

    def step(self, tau: _Pair, dt: float) -> None:
        """RK4 over ``dt`` (s) with the torque ``tau`` (N m) held; the mechanical stops at +-1.3 rad."""
        q, v, t = (float(self.q[0]), float(self.q[1])), (float(self.v[0]), float(self.v[1])), self.t

        def ahead(x: _Pair, dx: _Pair, f: float) -> _Pair:
            return x[0] + f * dx[0], x[1] + f * dx[1]

        k1 = (v, self._accel(q, v, tau, t))
        k2 = (
            ahead(v, k1[1], dt / 2),
            self._accel(ahead(q, k1[0], dt / 2), ahead(v, k1[1], dt / 2), tau, t + dt / 2),
        )
        k3 = (
            ahead(v, k2[1], dt / 2),
            self._accel(ahead(q, k2[0], dt / 2), ahead(v, k2[1], dt / 2), tau, t + dt / 2),
        )
        k4 = (ahead(v, k3[1], dt), self._accel(ahead(q, k3[0], dt), ahead(v, k3[1], dt), tau, t + dt))
        new_q = [q[k] + dt / 6 * (k1[0][k] + 2 * k2[0][k] + 2 * k3[0][k] + k4[0][k]) for k in range(2)]
        new_v = [v[k] + dt / 6 * (k1[1][k] + 2 * k2[1][k] + 2 * k3[1][k] + k4[1][k]) for k in range(2)]
        for k in range(2):  # mechanical stops
            if abs(new_q[k]) > 1.3:
                new_q[k], new_v[k] = math.copysign(1.3, new_q[k]), 0.0
        self.q, self.v, self.t = np.array(new_q), np.array(new_v), t + dt

    def counts(self) -> list[int]:
        """The encoders' positions (UNSIGNED32), measured with 0.001 rad of noise."""
        measured = self.q + self.noise.normal(0.0, 0.001, 2)
        return [
            (zero + sign * round(angle / (2 * math.pi) * cpr)) % (1 << 32)
            for angle, cpr, zero, sign in zip(measured, COUNTS_PER_REV, ZERO_COUNTS, DIRECTION, strict=True)
        ]


class IndependentBench:
    """The four nodes on ``bus``; the plant goes live when both valves are first ACTIVE.

    Args:
        bus: The CAN bus.
        duration_s: Live plant time after which :attr:`done` is set (s; 0: never).
        clock: ``"sync"`` (0x1006 x the periods the SYNC counter counts) or ``"wall"`` (monotonic clock).
        keep_answering: After ``duration_s``, keep sending TPDOs (real time); else fall silent (lockstep).
        receive_deadline: The valves watch their receive deadline (0x1400:05); off, a slow host's late
            setpoints fault no valve (a test of what else faults).
    """

    def __init__(
        self,
        bus: can.BusABC,
        duration_s: float = 0.0,
        clock: str = "sync",
        keep_answering: bool = False,
        receive_deadline: bool = True,
    ) -> None:
        if clock not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {clock!r}")
        self.network = canopen.Network(bus)
        self.lock = threading.Lock()
        self.valves = [Valve() for _ in VALVE_NODES]
        self.plant = Plant()
        self.clock = clock
        self.keep_answering = keep_answering
        self.receive_deadline = receive_deadline
        self.duration_steps = round(duration_s / _STEP_S)
        self.done = threading.Event()
        self.syncs = 0
        self.live_syncs = 0
        self.live_steps = 0
        """1 ms plant steps since live."""
        self.skipped = 0
        """Periods the SYNC counter said passed without a SYNC (live)."""
        self.held = 0
        """Live SYNCs with both valves ACTIVE at which a valve had no new setpoint."""
        self.answer_us: list[float] = []
        """Live: the later valve's RPDO after the TPDOs of the SYNC before (us)."""
        self._counter: int | None = None
        self._live_ns = 0
        self._sent_ns = 0
        self._arrived_ns = [0, 0]
        self.received: list[tuple[int, int] | None] = [None, None]
        self.quiet = [0, 0]
        self.valve_nodes = [canopen.LocalNode(n, str(HERE / "valve.eds")) for n in VALVE_NODES]
        self.encoder_nodes = [canopen.LocalNode(n, str(HERE / "encoder.eds")) for n in ENCODER_NODES]
        for node in (*self.valve_nodes, *self.encoder_nodes):
            self.network.add_node(node)
            node.tpdo.read(from_od=True)
        for index, node in enumerate(self.valve_nodes):
            node.rpdo.read(from_od=True)
            node.rpdo[1].add_callback(lambda pdo, index=index: self._on_rpdo(index, pdo))
        self.network.subscribe(0x80, self._on_sync)
        for node in (*self.valve_nodes, *self.encoder_nodes):  # before listening: no SDO before boot-up
            node.nmt.send_command(0x81)  # reset: boot-up, PRE-OPERATIONAL
        self.network.connect()

    def _on_rpdo(self, index: int, pdo: canopen.pdo.PdoMap) -> None:
        with self.lock:
            self.received[index] = (int(pdo[0x6040].raw), int(pdo[0x6300].raw))
            self._arrived_ns[index] = time.monotonic_ns()

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self.lock:
            periods = 1
            if data:  # the SYNC counter (CiA 301): the periods since the last SYNC, those without one too
                if self._counter is not None:
                    periods = (data[0] - self._counter - 1) % _COUNTER_OVERFLOW + 1
                self._counter = data[0]
            self.sync(periods)

    def _steps(self, period_us: int, periods: int, now_ns: int) -> int:
        """The 1 ms plant steps of this live SYNC: its periods' (on ``"sync"``) or the wall clock's."""
        if self.clock == "sync":
            return max(1, round(period_us / 1000)) * periods
        if not self.live_syncs:  # the first live SYNC moves one period, as on "sync"
            self._live_ns = now_ns - period_us * 1000
        return max(0, (now_ns - self._live_ns) // _STEP_NS - self.live_steps)

    def sync(self, periods: int = 1) -> None:
        """One SYNC, ``periods`` cycle periods after the last: latch, deadline, plant, TPDOs."""
        now_ns = time.monotonic_ns()
        self.syncs += 1
        node0 = self.valve_nodes[0]
        period_us = int(node0.sdo[0x1006].raw) or 1000
        if self.live_syncs and all(valve.active for valve in self.valves):
            self.skipped += periods - 1
            if any(received is None for received in self.received):
                self.held += 1
            else:
                self.answer_us.append((max(self._arrived_ns) - self._sent_ns) / 1e3)
        for index, (valve, node) in enumerate(zip(self.valves, self.valve_nodes, strict=True)):
            received, self.received[index] = self.received[index], None
            if received is not None:
                self.quiet[index] = 0
                valve.take(*received)
                continue
            self.quiet[index] += 1
            deadline_ms = int(node.sdo[0x1400][5].raw) if self.receive_deadline else 0
            late = deadline_ms and self.quiet[index] * period_us > deadline_ms * 1000
            if late and valve.status & _D and not valve.faulted:
                valve.status = _FAULT_DISABLED
                node.emcy.send(_EMCY_RPDO_TIMEOUT, register=0x11)
        if self.live_syncs or all(valve.active for valve in self.valves):
            steps = self._steps(period_us, periods, now_ns)
            for valve in self.valves:  # an ideal valve: the spool at its demand (docs/HW_CANOPEN.md)
                valve.spool = valve.demand()
            torque = (self.valves[0].spool * FULL_SCALE_NM[0], self.valves[1].spool * FULL_SCALE_NM[1])
            for _ in range(steps):
                self.plant.step(torque, _STEP_S)
            self.live_syncs += 1
            self.live_steps += steps
            if 0 < self.duration_steps <= self.live_steps:
                self.done.set()
        silent = self.done.is_set() and not self.keep_answering
        if silent or not all(
            node.nmt.state == "OPERATIONAL" for node in (*self.valve_nodes, *self.encoder_nodes)
        ):
            return  # after its duration the bench falls silent: a lockstep run halts there
        for valve, node in zip(self.valves, self.valve_nodes, strict=True):
            tpdo = node.tpdo[1]
            tpdo[0x6301].raw = round(valve.spool * 16384)
            tpdo[0x6381].raw = SUPPLY_UNITS
            tpdo[0x6041].raw = valve.status
            tpdo.transmit()
        for node, count, speed in zip(self.encoder_nodes, self.plant.counts(), self.plant.v, strict=True):
            tpdo = node.tpdo[1]
            tpdo[0x6030].raw = max(-32768, min(32767, round(speed * 1000)))
            tpdo[0x6004].raw = count
            tpdo.transmit()
        self._sent_ns = time.monotonic_ns()

    def figures(self) -> dict[str, object]:
        """What the bench saw: SYNCs, live plant time, periods skipped, held SYNCs, answer percentiles."""
        with self.lock:
            answers = np.asarray(self.answer_us)
            p50, p99, worst = np.percentile(answers, (50, 99, 100)).tolist() if answers.size else [None] * 3
            return {
                "syncs": self.syncs,
                "live_syncs": self.live_syncs,
                "live_s": self.live_steps * _STEP_S,
                "skipped_periods": self.skipped,
                "held_syncs": self.held,
                "answer_p50_us": p50,
                "answer_p99_us": p99,
                "answer_max_us": worst,
                "clock": self.clock,
            }

    def close(self) -> None:
        for node in (*self.valve_nodes, *self.encoder_nodes):
            node.nmt.stop_heartbeat()
        self.network.disconnect()
