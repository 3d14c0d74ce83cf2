"""Random frames onto the bus the CANopen master listens on, and the oracle (docs/HW_CANOPEN.md).

One episode: the master (:class:`CanopenDevice`) and the emulated bench on a python-can ``virtual`` channel,
armed, then cycles of the loop's commands with foreign frames sent by a third bus between a command and its
feedback. Used by tests/hw_bridge/test_canopen_fuzz.py (hypothesis) and bench/bench_canopen_fuzz.py (timed).
"""

from __future__ import annotations

import itertools
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field

import can
from smm_bench_emulator.canopen_bench import CanBench, CanBenchConfig, eds_path
from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.canopen_device import CanopenDevice
from smm_hw_bridge.cia408 import SPOOL_FULL_SCALE, ValveState, control_word
from smm_hw_bridge.protocol import FeedbackFrame
from udp_bench import answer

VALVES = (1, 2)
ENCODERS = (11, 12)
MASTER_ONLY = frozenset(
    {0x000, 0x080, *(0x200 + node for node in VALVES), *(0x600 + node for node in (*VALVES, *ENCODERS))}
)
"""COB-IDs only the master sends (NMT, SYNC, the valves' RPDO1, SDO requests): another sender's frame there
changes a node's state, and must end in a fault."""
LINK_IDS = tuple(
    sorted(
        MASTER_ONLY | {base + node for base in (0x080, 0x180, 0x580, 0x700) for node in (*VALVES, *ENCODERS)}
    )
)
"""Every COB-ID the link uses (the nodes' EMCY, TPDO1, SDO answers and heartbeats besides)."""
_DISABLED = control_word(ValveState.DISABLED)
_READ_S = 5.0
_CHANNELS = itertools.count()


@dataclass(frozen=True)
class Injection:
    """A foreign frame, sent after the command of cycle ``cycle`` (before its feedback is read)."""

    cycle: int
    arbitration_id: int
    data: bytes
    extended: bool = False
    remote: bool = False

    @property
    def changes_state(self) -> bool:
        """On a COB-ID only the master sends, a data frame (canopen ignores remote frames)."""
        return self.arbitration_id in MASTER_ONLY and not self.remote

    def message(self) -> can.Message:
        return can.Message(
            arbitration_id=self.arbitration_id,
            data=b"" if self.remote else self.data,
            dlc=len(self.data),
            is_extended_id=self.extended,
            is_remote_frame=self.remote,
        )


@dataclass
class Outcome:
    """What one episode saw, and what of the oracle failed (``violations``: empty when it held)."""

    faults: list[str] = field(default_factory=list)
    violations: list[str] = field(default_factory=list)
    rpdos: int = 0
    cycles: int = 0


class _Recorder:
    """Wraps a bus's ``send``: keeps the master's valve RPDOs (COB-ID, control word, setpoint)."""

    def __init__(self, bus: can.BusABC) -> None:
        self.sent: list[tuple[int, int, int]] = []
        self._send = bus.send
        bus.send = self.send  # type: ignore[method-assign]

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.arbitration_id in (0x200 + node for node in VALVES):
            word, setpoint = struct.unpack("<Hh", bytes(msg.data[:4]))
            self.sent.append((msg.arbitration_id, word, setpoint))
        self._send(msg, timeout)


def _feedback(device: CanopenDevice, outcome: Outcome) -> FeedbackFrame | None:
    reading = device.read(_READ_S)
    if not isinstance(reading, FeedbackFrame):
        outcome.violations.append(f"no feedback within {_READ_S} s (got {reading!r})")
        return None
    return reading


def run_episode(
    injections: Sequence[Injection], codes: Sequence[tuple[int, int]], *, arm_cycles: int = 4
) -> Outcome:
    """Arms, runs ``codes`` (one command a cycle) with ``injections``, then two clean cycles; the oracle."""
    outcome = Outcome()
    channel = f"smm-fuzz-{next(_CHANNELS)}"
    bench = CanBench(CanBenchConfig(), can.Bus(interface="virtual", channel=channel))
    master_bus = can.Bus(interface="virtual", channel=channel)
    recorder = _Recorder(master_bus)
    injector = can.Bus(interface="virtual", channel=channel)
    config = CanopenConfig(
        interface="virtual",
        valve_eds=str(eds_path("valve_cia408.eds")),
        encoder_eds=str(eds_path("encoder_cia406.eds")),
        heartbeat_ms=1000,  # consumers 3 s: a loaded machine's late heartbeat faults no episode
        pdo_validity_ms=300,
    )
    device = CanopenDevice(config, master_bus)
    try:
        device.open()
        _drive(
            device=device,
            bench=bench,
            recorder=recorder,
            injector=injector,
            injections=injections,
            codes=codes,
            arm_cycles=arm_cycles,
            outcome=outcome,
        )
    except Exception as error:  # the oracle: nothing the bus carries makes the master raise
        outcome.violations.append(f"raised {type(error).__name__}: {error}")
    finally:
        outcome.faults = list(device.faults)
        device.close()
        bench.close()
        injector.shutdown()
    return outcome


def _drive(
    *,
    device: CanopenDevice,
    bench: CanBench,
    recorder: _Recorder,
    injector: can.BusABC,
    injections: Sequence[Injection],
    codes: Sequence[tuple[int, int]],
    arm_cycles: int,
    outcome: Outcome,
) -> None:
    feedback = _feedback(device, outcome)
    plan = [(3000, -3000)] * arm_cycles + list(codes) + [(1000, 1000)] * 2
    last_injection = max((i.cycle for i in injections), default=-1) + arm_cycles
    for cycle, command_codes in enumerate(plan):
        if feedback is None:
            return
        faulted = bool(device.faults)
        before = len(recorder.sent)
        device.write(answer(feedback, cycle + 1, command_codes))
        for injection in injections:
            if injection.cycle + arm_cycles == cycle:
                injector.send(injection.message())
        feedback = _feedback(device, outcome)
        outcome.cycles += 1
        for cob_id, word, setpoint in recorder.sent[before:]:
            if abs(setpoint) > SPOOL_FULL_SCALE:
                outcome.violations.append(
                    f"setpoint {setpoint} beyond +-{SPOOL_FULL_SCALE} sent to 0x{cob_id:03X}"
                )
            if faulted and (word != _DISABLED or setpoint):
                outcome.violations.append(
                    f"after the fault {device.faults[0]!r}: control word 0x{word:04X}, setpoint {setpoint} "
                    f"sent to 0x{cob_id:03X} at cycle {cycle}"
                )
        if cycle == last_injection + 1 and any(i.changes_state for i in injections) and not device.faults:
            changing = [f"0x{i.arbitration_id:03X}" for i in injections if i.changes_state]
            outcome.violations.append(f"frames on {changing} (only a master sends those) left no fault")
    outcome.rpdos = len(recorder.sent)
    if device.faults:
        moving = [
            f"{valve.node.id}: {valve.machine.state.name}, spool {valve.spool}" for valve in bench.valves
        ]
        if any(valve.machine.follows_setpoint and valve.spool for valve in bench.valves):
            outcome.violations.append(f"faulted ({device.faults[0]!r}) yet a valve in motion: {moving}")
