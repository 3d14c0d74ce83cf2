"""CiA 408 (fluid power) valve objects and its device state machine, pure: no bus, no ROS.

Objects, bits and states as docs/HW_CANOPEN.md lists them (the control word's D, H, M bits cumulative,
R resetting a fault on its rising edge; the status word's R, M, H, D bits echoing the state reached).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Final

__all__ = [
    "CONTROL_MODE",
    "CONTROL_WORD",
    "DEVICE_MODE",
    "DEVICE_MODE_BUS",
    "DEVICE_TYPE",
    "POSITION",
    "PRESSURE_ACTUAL",
    "PROFILE_ENCODER",
    "PROFILE_VALVE",
    "SPOOL_ACTUAL",
    "SPOOL_FULL_SCALE",
    "SPOOL_SETPOINT",
    "STATUS_WORD",
    "ControlBit",
    "ValveState",
    "ValveStateMachine",
    "control_word",
    "state_of_status",
]

DEVICE_TYPE: Final[int] = 0x1000
PROFILE_VALVE: Final[int] = 408
PROFILE_ENCODER: Final[int] = 406
CONTROL_WORD: Final[int] = 0x6040
STATUS_WORD: Final[int] = 0x6041
DEVICE_MODE: Final[int] = 0x6042
DEVICE_MODE_BUS: Final[int] = 1
"""0x6042 = 1: the setpoint comes from the bus (a real valve may follow its analog input otherwise)."""
CONTROL_MODE: Final[int] = 0x6043
SPOOL_SETPOINT: Final[tuple[int, int]] = (0x6300, 1)
SPOOL_ACTUAL: Final[tuple[int, int]] = (0x6301, 1)
PRESSURE_ACTUAL: Final[tuple[int, int]] = (0x6381, 1)
POSITION: Final[int] = 0x6004
"""CiA 406: the encoder's position value (32-bit)."""
SPOOL_FULL_SCALE: Final[int] = 16384
"""Spool setpoint / actual at 100 % opening (INT16, symmetric: -16384 is -100 %)."""


class ControlBit(enum.IntFlag):
    """Control word 0x6040 bits (status word 0x6041 uses the same positions, R meaning ready)."""

    D = 0x1
    H = 0x2
    M = 0x4
    R = 0x8


class ValveState(enum.Enum):
    """Device states, by their status word bits R M H D."""

    NOT_READY = 0b0000
    INIT = 0b1000
    DISABLED = 0b1001
    HOLD = 0b1011
    ACTIVE = 0b1111
    FAULT_DISABLED = 0b0001
    FAULT_HOLD = 0b0011
    FAULT_REACTION = 0b0111

    @property
    def fault(self) -> bool:
        """A fault state (bit R clear past NOT_READY)."""
        return self in _FAULTS


_FAULTS: Final[frozenset[ValveState]] = frozenset(
    {ValveState.FAULT_DISABLED, ValveState.FAULT_HOLD, ValveState.FAULT_REACTION}
)
_BY_BITS: Final[dict[int, ValveState]] = {state.value: state for state in ValveState}
_REQUESTED: Final[tuple[ValveState, ...]] = (ValveState.INIT, ValveState.DISABLED, ValveState.HOLD)


def control_word(state: ValveState, *, reset: bool = False) -> int:
    """The control word that requests ``state`` (INIT, DISABLED, HOLD or ACTIVE), R set if ``reset``."""
    if state not in (*_REQUESTED, ValveState.ACTIVE):
        raise ValueError(f"a control word requests INIT, DISABLED, HOLD or ACTIVE, not {state.name}")
    return (state.value & 0b0111) | (int(ControlBit.R) if reset else 0)


def state_of_status(status: int) -> ValveState | None:
    """The state a status word reports (its low four bits), None if they name none."""
    return _BY_BITS.get(status & 0xF)


def _requested(word: int) -> ValveState:
    """The state the D, H, M bits ask for: cumulative, so a gap stops at the last set bit below it."""
    if not word & ControlBit.D:
        return ValveState.INIT
    if not word & ControlBit.H:
        return ValveState.DISABLED
    return ValveState.ACTIVE if word & ControlBit.M else ValveState.HOLD


@dataclass
class ValveStateMachine:
    """One valve's device state machine (the emulator's; the master reads it from the status word).

    Attributes:
        state: The state now (INIT after power-on).
        control: The last control word received.
    """

    state: ValveState = ValveState.INIT
    control: int = 0

    def command(self, word: int) -> ValveState:
        """Takes a control word: R's rising edge leaves a fault for DISABLED; otherwise D, H, M move."""
        rising_reset = bool(word & ControlBit.R) and not self.control & ControlBit.R
        self.control = word & 0xFFFF
        if self.state.fault:
            if rising_reset:
                self.state = ValveState.DISABLED if word & ControlBit.D else ValveState.INIT
            return self.state
        self.state = _requested(word)
        return self.state

    def fault(self) -> ValveState:
        """A fault detected: to FAULT_DISABLED (the emulated valve's fault reaction closes the spool)."""
        self.state = ValveState.FAULT_DISABLED
        return self.state

    @property
    def status(self) -> int:
        """The status word: the state's R M H D bits."""
        return self.state.value

    @property
    def follows_setpoint(self) -> bool:
        """ACTIVE: the bus setpoint drives the spool (HOLD: the hold setpoint; else the failsafe null)."""
        return self.state is ValveState.ACTIVE
