"""One node of the CANopen link as the master keeps it: what it is, what its last TPDO and heartbeat said."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

import canopen

from smm_hw_bridge.canopen_config import JOINTS
from smm_hw_bridge.protocol import FaultBit

__all__ = ["FAULT_BIT", "CanNode"]

FAULT_BIT: Final[dict[str, FaultBit]] = {"valve": FaultBit.VALVE_DRIVER, "encoder": FaultBit.ENCODER}
"""The feedback's fault bit of a node's own fault (EMCY, lost heartbeat, late or malformed TPDO), by kind."""


@dataclass
class CanNode:
    """One configured node (``kind``: ``valve`` or ``encoder``) and what its last TPDO and heartbeat said."""

    kind: str
    joint: int
    remote: canopen.RemoteNode
    identity: tuple[int, int, int, int] = (0, 0, 0, 0)
    device_type: int = 0
    values: dict[int, int] = field(default_factory=dict)
    sync: int = -1
    heard: float = 0.0
    """When its last heartbeat came (monotonic s)."""
    lost: bool = False
    operational: bool = False
    """A heartbeat said OPERATIONAL since the start."""

    @property
    def name(self) -> str:
        """How faults and the log name it: ``valve alpha (node 1)``."""
        return f"{self.kind} {JOINTS[self.joint]} (node {self.remote.id})"
