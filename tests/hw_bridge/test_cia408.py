"""The CiA 408 device state machine: cumulative D, H, M bits, faults left only by R's rising edge."""

from __future__ import annotations

import pytest
from smm_hw_bridge.cia408 import ControlBit, ValveState, ValveStateMachine, control_word, state_of_status

D, H, M, R = (int(bit) for bit in (ControlBit.D, ControlBit.H, ControlBit.M, ControlBit.R))


@pytest.mark.parametrize(
    ("word", "state"),
    [
        (0, ValveState.INIT),
        (D, ValveState.DISABLED),
        (D | H, ValveState.HOLD),
        (D | H | M, ValveState.ACTIVE),
        (H | M, ValveState.INIT),
        (D | M, ValveState.DISABLED),
    ],
)
def test_the_bits_are_cumulative(word: int, state: ValveState) -> None:
    machine = ValveStateMachine()
    assert machine.command(word) is state
    assert machine.status == state.value
    assert state_of_status(machine.status) is state
    assert machine.follows_setpoint == (state is ValveState.ACTIVE)


def test_a_fault_is_left_only_on_the_rising_edge_of_r() -> None:
    machine = ValveStateMachine()
    machine.command(D | H | M)
    machine.fault()
    assert machine.state is ValveState.FAULT_DISABLED and machine.state.fault
    assert machine.command(D | H | M) is ValveState.FAULT_DISABLED  # asking for ACTIVE does not leave it
    assert machine.status & R == 0  # not ready
    assert machine.command(D | R) is ValveState.DISABLED  # rising R
    machine.fault()
    assert machine.command(D | R) is ValveState.FAULT_DISABLED  # R held high: no new edge
    assert machine.command(D) is ValveState.FAULT_DISABLED
    assert machine.command(D | R) is ValveState.DISABLED


def test_control_word_requests_each_state_and_refuses_a_fault_state() -> None:
    for state in (ValveState.INIT, ValveState.DISABLED, ValveState.HOLD, ValveState.ACTIVE):
        assert ValveStateMachine().command(control_word(state)) is state
    assert control_word(ValveState.DISABLED, reset=True) == D | R
    with pytest.raises(ValueError, match="FAULT_DISABLED"):
        control_word(ValveState.FAULT_DISABLED)


def test_an_unknown_status_names_no_state() -> None:
    assert state_of_status(0b0101) is None
