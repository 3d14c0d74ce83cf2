"""A second CANopen bench, written from the CiA 301 / 406 / 408 object lists alone (no smm_bench_emulator).

Two valves (nodes 21, 22) and two encoders (31, 32) as ``canopen`` LocalNodes with this folder's EDS files
(other PDO orders than the emulator's, device types with the high word set), and a plant of its own: the
SPEC's 2-DOF dynamics (M(q) of its Appendix A, C by Christoffel symbols of M by central differences,
gravity, viscous friction, case 2's disturbance and +10 % inertias), ideal valves (+-``FULL_SCALE_NM`` at
+-16384, no lag), encoders of ``COUNTS_PER_REV`` with their own zero and direction. Each SYNC:
the last RPDO latched, the plant moved one cycle period (0x1006) at 1 kHz sub-steps, the TPDOs sent.
"""

from __future__ import annotations

import math
import threading
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

    def mass(self, q: np.ndarray) -> np.ndarray:
        a, b = q
        sec2 = 1.0 / math.cos(a) ** 2
        d = math.tan(a) ** 2 + math.cos(b) ** 2
        m11 = self.i44 + sec2 * math.cos(b) ** 2 / d**2 * (self.i55 * sec2 - self.i11 * d)
        m12 = math.tan(a) * math.sin(b) * math.cos(b) / d**2 * (self.i55 * sec2 - 0.5 * self.i11 * d)
        m22 = self.i22 + self.i55 * math.tan(a) ** 2 * math.sin(b) ** 2 / d**2
        return np.array([[m11, m12], [m12, m22]])

    def _accel(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, t: float) -> np.ndarray:
        h = 1e-6
        dm = [(self.mass(q + h * e) - self.mass(q - h * e)) / (2 * h) for e in np.eye(2)]
        coriolis = np.array(
            [
                sum(
                    0.5 * (dm[i][k, j] + dm[j][k, i] - dm[k][i, j]) * v[i] * v[j]
                    for i in range(2)
                    for j in range(2)
                )
                for k in range(2)
            ]
        )
        gravity = np.array([0.0, -self.mgl * math.sin(q[1])])
        disturbance = np.array([-0.5, 0.5]) * math.cos(7 * t) if t > 1.0 else np.zeros(2)
        rhs = tau - coriolis - gravity - self.friction * v - disturbance
        return np.linalg.solve(self.mass(q), rhs)

    def step(self, tau: np.ndarray, dt: float) -> None:
        q, v, t = self.q, self.v, self.t
        k1 = (v, self._accel(q, v, tau, t))
        k2 = (v + 0.5 * dt * k1[1], self._accel(q + 0.5 * dt * k1[0], v + 0.5 * dt * k1[1], tau, t + dt / 2))
        k3 = (v + 0.5 * dt * k2[1], self._accel(q + 0.5 * dt * k2[0], v + 0.5 * dt * k2[1], tau, t + dt / 2))
        k4 = (v + dt * k3[1], self._accel(q + dt * k3[0], v + dt * k3[1], tau, t + dt))
        self.q = q + dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        self.v = v + dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        stops = np.abs(self.q) > 1.3  # mechanical stops
        self.q = np.clip(self.q, -1.3, 1.3)
        self.v[stops] = 0.0
        self.t = t + dt

    def counts(self) -> list[int]:
        """The encoders' positions (UNSIGNED32), measured with 0.001 rad of noise."""
        measured = self.q + self.noise.normal(0.0, 0.001, 2)
        return [
            (zero + sign * round(angle / (2 * math.pi) * cpr)) % (1 << 32)
            for angle, cpr, zero, sign in zip(measured, COUNTS_PER_REV, ZERO_COUNTS, DIRECTION, strict=True)
        ]


class IndependentBench:
    """The four nodes on ``bus``; ``live_syncs`` counts SYNCs since both valves were first ACTIVE."""

    def __init__(self, bus: can.BusABC, duration_syncs: int = 0) -> None:
        self.network = canopen.Network(bus)
        self.lock = threading.Lock()
        self.valves = [Valve() for _ in VALVE_NODES]
        self.plant = Plant()
        self.live_syncs = 0
        self.duration_syncs = duration_syncs
        self.done = threading.Event()
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
        self.network.connect()
        for node in (*self.valve_nodes, *self.encoder_nodes):
            node.nmt.send_command(0x81)  # reset: boot-up, PRE-OPERATIONAL

    def _on_rpdo(self, index: int, pdo: canopen.pdo.PdoMap) -> None:
        with self.lock:
            self.received[index] = (int(pdo[0x6040].raw), int(pdo[0x6300].raw))

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self.lock:
            self.sync()

    def sync(self) -> None:
        """One SYNC: latch, deadline, plant, TPDOs."""
        node0 = self.valve_nodes[0]
        period_us = int(node0.sdo[0x1006].raw) or 1000
        for index, (valve, node) in enumerate(zip(self.valves, self.valve_nodes, strict=True)):
            received, self.received[index] = self.received[index], None
            if received is not None:
                self.quiet[index] = 0
                valve.take(*received)
                continue
            self.quiet[index] += 1
            deadline_ms = int(node.sdo[0x1400][5].raw)
            late = deadline_ms and self.quiet[index] * period_us > deadline_ms * 1000
            if late and valve.status & _D and not valve.faulted:
                valve.status = _FAULT_DISABLED
                node.emcy.send(_EMCY_RPDO_TIMEOUT, register=0x11)
        if self.live_syncs or all(valve.active for valve in self.valves):
            for _ in range(max(1, round(period_us / 1000))):
                for valve in self.valves:  # an ideal valve: the spool at its demand (docs/HW_CANOPEN.md)
                    valve.spool = valve.demand()
                torque = np.array([v.spool * fs for v, fs in zip(self.valves, FULL_SCALE_NM, strict=True)])
                self.plant.step(torque, _STEP_S)
            self.live_syncs += 1
            if self.live_syncs == self.duration_syncs:
                self.done.set()
        if self.done.is_set() or not all(
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

    def close(self) -> None:
        for node in (*self.valve_nodes, *self.encoder_nodes):
            node.nmt.stop_heartbeat()
        self.network.disconnect()
