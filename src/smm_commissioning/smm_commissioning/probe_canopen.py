"""``probe`` on the CANopen link: what the bus offers checked, each finding naming the node.

Every node's device type (configure refused a wrong one), its NMT state from its heartbeat, each valve's
state (DISABLED with the output disabled) and its pressure actual 0x6381:01 (stuck, at a rail), the master's
faults (EMCY, a lost heartbeat, ...) with the node and the code, the stated supply (``canopen.supply_bar``).
docs/COMMISSIONING.md, "On the CANopen link".
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np
from smm_hw_bridge.canopen_config import parameter
from smm_hw_bridge.canopen_device import CanopenDevice
from smm_hw_bridge.canopen_node import CanNode
from smm_hw_bridge.cia408 import PRESSURE_ACTUAL, STATUS_WORD, ValveState, state_of_status

from smm_commissioning.host import BenchHost

__all__ = ["HeartbeatWatch", "NodeReading", "canopen_findings", "pressure_actuals"]

_NMT_NAMES = {0: "BOOT-UP", 4: "STOPPED", 5: "OPERATIONAL", 127: "PRE-OPERATIONAL"}
_OPERATIONAL = 5
_FAULTS_SHOWN = 10
"""The master's faults a probe names, the first ones (a bus gone wrong faults at every SYNC)."""
_RAIL = 32767
"""|0x6381:01| at the INT16 rail: the transducer's signal out of its range (open or shorted)."""


@dataclass(frozen=True)
class NodeReading:
    """One node as probe found it.

    Attributes:
        name: How the master names it (``valve alpha (node 1)``).
        device_type: Its 0x1000 (the low 16 bits: 408 valve, 406 encoder).
        nmt: Its NMT state by its last heartbeat (``OPERATIONAL``, ...; ``none heard``).
        state: A valve's device state by its status word 0x6041 (``DISABLED``, ...); "" for an encoder.
        pressure: A valve's pressure actual 0x6381:01 over the reading (mean, std, span) (units); None for
            an encoder.
    """

    name: str
    device_type: int
    nmt: str
    state: str
    pressure: tuple[float, float, int] | None


class HeartbeatWatch:
    """Each node's NMT state from the heartbeats heard since it was made (canopen's heartbeat callbacks).

    Args:
        master: The opened CANopen master.
    """

    def __init__(self, master: CanopenDevice) -> None:
        self.master = master
        self.states: dict[str, int] = {}
        self.started = time.monotonic()
        for node in master.nodes:
            node.remote.nmt.add_heartbeat_callback(functools.partial(self._heard, node.name))

    def _heard(self, name: str, state: int) -> None:
        self.states[name] = state

    @property
    def wait_s(self) -> float:
        """How long a node may be silent (s): its consumer's time, 3 heartbeat periods, and a margin."""
        return 3 * self.master.config.heartbeat_ms / 1000.0 + 0.5

    def await_all(self, host: BenchHost) -> None:
        """Until every node was heard, at most :attr:`wait_s` from the start.

        In real time the host keeps answering (disabled: a valve's receive deadline runs on the wall clock);
        in lockstep the bench waits for the next SYNC, so the wait moves nothing.
        """
        deadline = self.started + self.wait_s
        while len(self.states) < len(self.master.nodes) and time.monotonic() < deadline:
            if self.master.clock is not None:
                host.answer(None)
            else:
                time.sleep(0.01)


def pressure_actuals(master: CanopenDevice) -> tuple[int, ...]:
    """Each valve's pressure actual 0x6381:01 in its last TPDO (units), in joint order."""
    return tuple(node.values.get(PRESSURE_ACTUAL[0], 0) for node in _valves(master))


def _valves(master: CanopenDevice) -> list[CanNode]:
    return [node for node in master.nodes if node.kind == "valve"]


def canopen_findings(
    master: CanopenDevice, watch: HeartbeatWatch, pressures: np.ndarray, supply_min: float
) -> tuple[list[str], list[str], tuple[NodeReading, ...]]:
    """What is wrong on the bus (findings), what could not be checked (notes), each node as read.

    ``pressures``: each valve's pressure actual at each feedback read, shape (n, 2) (units).
    """
    findings = [
        f"{fault}: clear its cause (the node's manual lists the code) and probe again"
        for fault in master.faults[:_FAULTS_SHOWN]
    ]
    if len(master.faults) > _FAULTS_SHOWN:
        findings.append(f"and {len(master.faults) - _FAULTS_SHOWN} more faults of the master after those")
    faulted = {fault.partition(":")[0] for fault in master.faults}
    supply = master.config.supply_bar
    if supply < supply_min:
        findings.append(
            f"supply pressure {supply:.2f} bar ({parameter('supply_bar')}: no CANopen node sends it, the "
            f"stated supply), below the {supply_min:g} bar the steps need: start the pump, open the supply "
            f"valve, read the supply gauge and state it in {parameter('supply_bar')}"
        )
    heard = f"within {watch.wait_s:.1f} s"
    spans = np.ptp(pressures, axis=0) if len(pressures) else np.zeros(2)
    nodes = []
    for node in master.nodes:
        state = watch.states.get(node.name)
        nmt = "none heard" if state is None else _NMT_NAMES.get(state, f"0x{state:02X}")
        if node.name not in faulted:
            if state is None:
                findings.append(
                    f"{node.name}: no heartbeat {heard}: check its power, its CAN wiring and termination, "
                    "its node id and bit rate"
                )
            elif state != _OPERATIONAL:
                findings.append(
                    f"{node.name}: NMT state {nmt} in its heartbeat, not OPERATIONAL after the master's "
                    "start: check its NMT start-up setting (its manual), power-cycle it"
                )
        valve_state, pressure = "", None
        if node.kind == "valve":
            status = node.values.get(STATUS_WORD, 0)
            reached = state_of_status(status)
            valve_state = reached.name if reached else f"unknown (0x{status:04X})"
            if reached is not ValveState.DISABLED and node.name not in faulted:
                findings.append(
                    f"{node.name}: device state {valve_state} (status word 0x6041 = 0x{status:04X}) while "
                    "the master asks DISABLED: check its device mode 0x6042 and its manual's state machine"
                )
            joint = node.joint
            series = pressures[:, joint] if len(pressures) else np.zeros(1)
            pressure = (float(np.mean(series)), float(np.std(series)), int(spans[joint]))
            findings += _pressure_findings(master, node, series, int(spans[1 - joint]))
        nodes.append(NodeReading(node.name, node.device_type, nmt, valve_state, pressure))
    notes = []
    if len(pressures) and not spans.any():
        notes.append(
            "neither pressure actual 0x6381:01 varied at rest: a stuck transducer cannot be told from a "
            "quiet one"
        )
    return findings, notes, tuple(nodes)


def _pressure_findings(
    master: CanopenDevice, node: CanNode, series: np.ndarray, other_span: int
) -> list[str]:
    """A valve's pressure actual at its rail, or stuck while the other valve's varies."""
    bar = master.config.bar_per_unit
    low, high = int(series.min()), int(series.max())
    other = _valves(master)[1 - node.joint].name
    if max(abs(low), abs(high)) >= _RAIL:
        return [
            f"{node.name}: pressure actual 0x6381:01 reads its rail ({low}..{high} units): its pressure "
            "transducer is unplugged or shorted; check it and its connector"
        ]
    if low == high and other_span > 0:
        return [
            f"{node.name}: pressure actual 0x6381:01 is stuck at {low} units ({low * bar:.2f} bar) over "
            f"{len(series)} SYNCs while {other}'s varies over {other_span} units: check the valve's pressure "
            "transducer and its connector"
        ]
    return []
