"""The emulated CANopen bench: two CiA 408 valves and two CiA 406 encoders as canopen LocalNodes.

The plant is the board's (:class:`~smm_bench_emulator.board.BoardCore`: its plant, valves and actuators with
their lag, lock and load pressure, and encoder counters), sub-stepped at its 1 kHz tick between SYNCs. Each
SYNC: the setpoints received since the last one are latched, the plant moves one cycle period (0x1006), the
TPDOs go out (each valve's pressure actual: its joint's load pressure). Every node consumes the master's
heartbeat (0x1016:01). docs/HW_CANOPEN.md.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Final

import can
import canopen
import numpy as np
from smm_hw_bridge.cia408 import (
    CONTROL_WORD,
    POSITION,
    PRESSURE_ACTUAL,
    SPOOL_ACTUAL,
    SPOOL_FULL_SCALE,
    SPOOL_SETPOINT,
    STATUS_WORD,
    ValveState,
    ValveStateMachine,
)
from smm_hw_bridge.protocol import CODE_MAX
from smm_hw_bridge.sync_clock import periods_between
from smm_schema.ranges import bounds, check_bounds

from smm_bench_emulator.board import BoardConfig, BoardCore

__all__ = [
    "EMCY_DEADLINE",
    "EMCY_HEARTBEAT",
    "CanBench",
    "CanBenchConfig",
    "eds_path",
]

SYNC_ID: Final[int] = 0x80
EMCY_DEADLINE: Final[int] = 0x8250
"""EMCY code of a valve whose RPDO missed its deadline (CiA 301: RPDO timeout)."""
EMCY_HEARTBEAT: Final[int] = 0x8130
"""EMCY code of a node whose consumer missed the master's heartbeat (CiA 301: heartbeat error)."""
_RPDO_EVENT_TIMER: Final[tuple[int, int]] = (0x1400, 5)
_CYCLE_PERIOD: Final[int] = 0x1006
_KEPT_ANSWERS: Final[int] = 1_000_000
_HEARTBEAT_CONSUMER: Final[tuple[int, int]] = (0x1016, 1)
_WATCH_S: Final[float] = 0.01
"""How often the consumers are checked (s)."""
_INT16: Final[int] = 32767


def eds_path(name: str) -> Path:
    """The shipped EDS file ``name`` (``valve_cia408.eds``, ``encoder_cia406.eds``)."""
    return Path(str(resources.files("smm_bench_emulator") / "eds" / name))


@dataclass(frozen=True)
class CanBenchConfig:
    """The emulated CANopen bench.

    Attributes:
        board: The plant, valves and encoders (the frame board's bench; its tick is the sub-step).
        valve_node_ids: Valve node ids (alpha, beta), in [1, 127].
        encoder_node_ids: Encoder node ids (alpha, beta), in [1, 127].
        bar_per_unit: Pressure actual 0x6381:01 (the joint's load pressure) per unit (bar), > 0.
        pressure_noise: Standard deviation of each valve's pressure transducer noise on 0x6381:01 (bar),
            >= 0, seeded by the board's seed (0: the load pressure exactly, to the unit).
        wait_active: The plant stands still until both valves are first ACTIVE (lockstep runs line up
            with the simulator's, whose step 0 is the controller's first answer).
        duration_syncs: Live SYNCs (the plant moving) after which :attr:`CanBench.done` is set (0: never).
    """

    board: BoardConfig = field(default_factory=BoardConfig)
    valve_node_ids: tuple[int, int] = field(default=(1, 2), metadata=bounds(1, 127))
    encoder_node_ids: tuple[int, int] = field(default=(11, 12), metadata=bounds(1, 127))
    bar_per_unit: float = field(default=0.01, metadata=bounds(1e-9, 1e3))
    pressure_noise: float = field(default=0.0, metadata=bounds(0.0, 1e3))
    wait_active: bool = False
    duration_syncs: int = field(default=0, metadata=bounds(0, 1 << 62))

    def __post_init__(self) -> None:
        check_bounds(self)
        ids = (*self.valve_node_ids, *self.encoder_node_ids)
        if len(set(ids)) != len(ids):
            raise ValueError(
                f"node ids must differ, got valves {self.valve_node_ids}, encoders {self.encoder_node_ids}"
            )


class _Valve:
    """One valve node: its state machine, the setpoint latched at SYNC, its receive deadline."""

    def __init__(self, node: canopen.LocalNode) -> None:
        self.node = node
        self.machine = ValveStateMachine()
        self.setpoint = 0
        self.received: tuple[int, int] | None = None
        self.received_ns: int | None = None
        """When the last RPDO came (monotonic ns), None before the first."""
        self.cycles_since_rpdo = 0
        node.rpdo.read(from_od=True)
        node.tpdo.read(from_od=True)
        node.rpdo[1].add_callback(self._on_rpdo)
        node.add_write_callback(self._on_sdo_write)

    def _on_sdo_write(self, index: int, subindex: int, od: object, data: bytes) -> None:
        if index == CONTROL_WORD:
            self.machine.command(int.from_bytes(data[:2], "little"))

    def _on_rpdo(self, pdo: canopen.pdo.PdoMap) -> None:
        self.received = (int(pdo[CONTROL_WORD].raw), int(pdo[SPOOL_SETPOINT[0]].raw))
        self.received_ns = time.monotonic_ns()

    @property
    def deadline_ms(self) -> int:
        """The receive deadline 0x1400:05 (ms, 0: none)."""
        return int(self.node.sdo[_RPDO_EVENT_TIMER[0]][_RPDO_EVENT_TIMER[1]].raw)

    def miss_deadline(self) -> None:
        """No setpoint within the deadline: the fault and its EMCY (once; not before the first start)."""
        if not self.machine.state.fault and self.machine.state is not ValveState.INIT:
            self.machine.fault()
            self.node.emcy.send(EMCY_DEADLINE, register=0x11)

    def latch(self, cycle_us: int, periods: int = 1) -> None:
        """At SYNC, ``periods`` cycles after the last: the last RPDO, or the deadline (0x1400:05) checked."""
        received, self.received = self.received, None
        if received is None:
            self.cycles_since_rpdo += periods
            deadline_ms = self.deadline_ms
            if deadline_ms > 0 and self.cycles_since_rpdo * cycle_us > deadline_ms * 1000:
                self.miss_deadline()
            return
        self.cycles_since_rpdo = 0
        word, setpoint = received
        self.machine.command(word)
        self.setpoint = max(-SPOOL_FULL_SCALE, min(SPOOL_FULL_SCALE, setpoint))

    @property
    def spool(self) -> int:
        """Spool position now (the setpoint when ACTIVE, else the failsafe null)."""
        return self.setpoint if self.machine.follows_setpoint else 0

    def transmit(self, pressure: float) -> None:
        """TPDO1: status word, spool actual, ``pressure`` (its joint's load pressure, units of 0x6381:01)."""
        tpdo = self.node.tpdo[1]
        tpdo[STATUS_WORD].raw = self.machine.status
        tpdo[SPOOL_ACTUAL[0]].raw = self.spool
        tpdo[PRESSURE_ACTUAL[0]].raw = max(-_INT16, min(_INT16, round(pressure)))
        tpdo.transmit()


class _Consumer:
    """A node's heartbeat consumer 0x1016:01 (producer id in bits 16-23, time in ms in bits 0-15).

    Watching starts at the producer's first heartbeat after the entry is written (CiA 301); none for that
    long and ``lost`` is set once until one comes again.
    """

    def __init__(self, node: canopen.LocalNode, network: canopen.Network) -> None:
        self.node = node
        self.network = network
        self.heard: float | None = None
        self.lost = False
        self.time_s = 0.0
        node.add_write_callback(self._on_write)

    def _on_write(self, index: int, subindex: int, od: object, data: bytes) -> None:
        if (index, subindex) != _HEARTBEAT_CONSUMER:
            return
        value = int.from_bytes(data[:4], "little")
        self.time_s, self.heard, self.lost = (value & 0xFFFF) / 1000.0, None, False
        if self.time_s > 0:
            self.network.subscribe(0x700 + ((value >> 16) & 0x7F), self._on_heartbeat)

    def _on_heartbeat(self, can_id: int, data: bytearray, timestamp: float) -> None:
        self.heard, self.lost = time.monotonic(), False

    def expired(self, now: float) -> bool:
        """True once when the producer's heartbeat has been missing for longer than the consumer time."""
        if self.lost or self.heard is None or self.time_s <= 0 or now - self.heard <= self.time_s:
            return False
        self.lost = True
        return True


class CanBench:
    """The four nodes on ``bus`` (python-can: ``udp_multicast`` between processes, ``virtual`` in one).

    Args:
        config: The bench.
        bus: The CAN bus (closed by :meth:`close`).
    """

    def __init__(self, config: CanBenchConfig, bus: can.BusABC) -> None:
        self.config = config
        self.board = BoardCore(config.board)
        self._noise = np.random.default_rng(config.board.seed)
        self.lock = threading.Lock()
        self.syncs = 0
        self.live_syncs = 0
        """Cycle periods since the plant went live (at once, or at the first ACTIVE with ``wait_active``):
        one a SYNC, or as many as its counter says passed (real time)."""
        self.active_syncs = 0
        """SYNCs at which both valves were ACTIVE (following the bus setpoint)."""
        self.held_syncs = 0
        """Of the live SYNCs with both valves ACTIVE, those without a new setpoint for a valve (held)."""
        self.skipped_periods = 0
        """Of those, the periods the SYNC counter said passed without a SYNC (real time; counted in held)."""
        self.answer_us: list[float] = []
        """Per live ACTIVE SYNC answered: the later valve's RPDO after the SYNC before it (us)."""
        self._sync_ns = 0
        self._counter: int | None = None
        self.done = threading.Event()
        """Set at ``duration_syncs`` live SYNCs."""
        self.network = canopen.Network(bus)
        self.valves: list[_Valve] = []
        self.encoders: list[canopen.LocalNode] = []
        for node_id in config.valve_node_ids:
            node = canopen.LocalNode(node_id, str(eds_path("valve_cia408.eds")))
            self.network.add_node(node)
            self.valves.append(_Valve(node))
        for node_id in config.encoder_node_ids:
            node = canopen.LocalNode(node_id, str(eds_path("encoder_cia406.eds")))
            self.network.add_node(node)
            node.tpdo.read(from_od=True)
            self.encoders.append(node)
        self.consumers = [_Consumer(node, self.network) for node in self._nodes()]
        self.network.subscribe(SYNC_ID, self._on_sync)
        for node in self._nodes():  # before listening: no SDO answered before the node's boot-up
            node.nmt.send_command(0x81)  # reset node: boot-up, then PRE-OPERATIONAL
            # (CiA 301 enters it by itself; canopen's LocalNode stays INITIALISING, whose heartbeat, started
            # by the master's 0x1017 write, would be a boot-up after the master's start)
            node.nmt.send_command(0x80)
        self.network.connect()
        self._closing = threading.Event()
        self._watcher = threading.Thread(target=self._watch, name="can_bench_heartbeats", daemon=True)
        self._watcher.start()

    def _watch(self) -> None:
        """The master's heartbeat missing: each valve to FAULT_DISABLED (spool null), every node's EMCY."""
        while not self._closing.wait(_WATCH_S):
            with self.lock:
                now = time.monotonic()
                for consumer in self.consumers:
                    if not consumer.expired(now):
                        continue
                    for valve in self.valves:
                        if valve.node is consumer.node and not valve.machine.state.fault:
                            valve.machine.fault()
                    consumer.node.emcy.send(EMCY_HEARTBEAT, register=0x11)

    def _nodes(self) -> list[canopen.LocalNode]:
        return [valve.node for valve in self.valves] + self.encoders

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self.lock:
            periods = 1
            if data:  # the SYNC counter (real time): the periods since the last SYNC, skipped ones too
                if self._counter is not None:
                    periods = periods_between(data[0], self._counter)
                self._counter = data[0]
            self.step(periods)

    def step(self, periods: int = 1) -> None:
        """A SYNC ``periods`` cycles after the last: latch, move the plant that long, send the TPDOs."""
        cycle_us = int(self.valves[0].node.sdo[_CYCLE_PERIOD].raw) or self.board.config.period_ns // 1000
        now, before = time.monotonic_ns(), self._sync_ns
        self._sync_ns = now
        if self.live_syncs and all(valve.machine.follows_setpoint for valve in self.valves):
            arrivals = [valve.received_ns or 0 for valve in self.valves if valve.received is not None]
            self.held_syncs += periods - 1  # skipped slots: the valves held the setpoint
            self.skipped_periods += periods - 1
            if len(arrivals) < len(self.valves):
                self.held_syncs += 1
            elif len(self.answer_us) < _KEPT_ANSWERS:
                self.answer_us.append((max(arrivals) - before) / 1e3)
        for valve in self.valves:
            valve.latch(cycle_us, periods)
        board = self.board
        board.output = [valve.spool * CODE_MAX / SPOOL_FULL_SCALE for valve in self.valves]
        active = all(valve.machine.follows_setpoint for valve in self.valves)
        self.active_syncs += active
        if self.live_syncs or active or not self.config.wait_active:
            substeps = max(1, round(cycle_us * 1000 / board.config.period_ns)) * periods
            for _ in range(substeps):  # not both ACTIVE: the failsafe spool, the oil trapped
                board.valves.move(board.plant, board.output_codes(), active, board.supply_pressure)
            before_live = self.live_syncs
            self.live_syncs += periods
            if before_live < self.config.duration_syncs <= self.live_syncs:
                self.done.set()
        self.syncs += 1
        if not all(node.nmt.state == "OPERATIONAL" for node in self._nodes()):
            return
        load = np.asarray(board.valves.load_pressure())
        if self.config.pressure_noise > 0:
            load = load + self._noise.normal(0.0, self.config.pressure_noise, len(self.valves))
        for valve, bar in zip(self.valves, load.tolist(), strict=True):
            valve.transmit(bar / self.config.bar_per_unit)
        for encoder, count in zip(self.encoders, self.board.counts(), strict=True):
            encoder.tpdo[1][POSITION].raw = count
            encoder.tpdo[1].transmit()

    def watch(self, now_ns: int) -> None:
        """Real time: a valve whose setpoints stopped for its deadline (wall clock) faults, SYNC or not."""
        with self.lock:
            for valve in self.valves:
                deadline_ms, received = valve.deadline_ms, valve.received_ns
                operational = valve.node.nmt.state == "OPERATIONAL"
                if operational and received is not None and 0 < deadline_ms * 1_000_000 < now_ns - received:
                    valve.miss_deadline()

    def valve_states(self) -> tuple[ValveState, ...]:
        """Each valve's device state (alpha, beta)."""
        with self.lock:
            return tuple(valve.machine.state for valve in self.valves)

    def close(self) -> None:
        """Stops heartbeats and the consumers' watch, and leaves the bus."""
        self._closing.set()
        self._watcher.join()
        for node in self._nodes():
            node.nmt.stop_heartbeat()
        self.network.disconnect()
