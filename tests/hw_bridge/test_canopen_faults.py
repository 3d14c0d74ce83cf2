"""The CANopen link's faults, each named with the node and the code, every valve DISABLED (lockstep).

A missing node, a wrong device type, a PDO mapping that differs from the EDS, a TPDO past its validity, a
lost heartbeat with the TPDOs still coming, a valve whose setpoints stop: test_canopen_device.py. Here too:
making the valves safe when the bench is gone (the SDO write of DISABLED unanswered).
"""

from __future__ import annotations

import logging
import re
import time
from pathlib import Path

import can
import pytest
from hw_bridge import test_canopen_device as emulated
from hw_bridge.test_canopen_device import _feedback, _open, _run
from smm_bench_emulator.canopen_bench import CanBench, eds_path
from smm_hw_bridge.canopen_device import ConfigureError
from smm_hw_bridge.cia408 import ValveState, control_word
from smm_hw_bridge.protocol import CommandFlag, FaultBit, FeedbackFrame
from udp_bench import answer

ENABLE = int(CommandFlag.ENABLE)
bench = emulated.bench  # the emulated bench on a fresh virtual channel (fixtures)
channel = emulated.channel


def test_a_wrong_identity_is_refused_naming_the_node_and_the_object(
    bench: CanBench, channel: str, tmp_path: Path
) -> None:
    text = eds_path("encoder_cia406.eds").read_text()
    other = text.replace(
        "[1018sub2]\nParameterName=Product code\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\n"
        "DefaultValue=0x00000406",
        "[1018sub2]\nParameterName=Product code\nObjectType=0x7\n"
        "DataType=0x0007\nAccessType=ro\nDefaultValue=0x00000999",
    )
    assert other != text
    user_eds = tmp_path / "encoder.eds"
    user_eds.write_text(other)
    with pytest.raises(
        ConfigureError,
        match=r"encoder alpha \(node 11\): identity 0x1018:02 \(product code\) = 0x00000406, its EDS .* says "
        r"0x00000999: another device",
    ):
        _open(channel, encoder_eds=str(user_eds))


def test_an_emcy_mid_run_is_a_fault_naming_the_node_and_its_code(bench: CanBench, channel: str) -> None:
    device = _open(channel)
    try:
        armed = _run(device, 5, (3000, 3000), ENABLE)
        assert bench.valve_states() == (ValveState.ACTIVE, ValveState.ACTIVE)
        bench.encoders[1].emcy.send(0x7305, register=0x81)
        device.write(answer(armed, 10, (3000, 3000), ENABLE))
        faulted = _until(device, lambda f: bool(f.faults), armed, 11)
        assert faulted.faults & FaultBit.ENCODER
        assert device.faults == ["encoder beta (node 12): EMCY 0x7305 (error register 0x81)"]
        _run(device, 1, (3000, 3000), ENABLE, start=50, feedback=faulted)
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
        assert [valve.spool for valve in bench.valves] == [0, 0]
    finally:
        device.close()


def _until(device, done, feedback: FeedbackFrame, start: int) -> FeedbackFrame:  # type: ignore[no-untyped-def]
    """Enabled cycles (at most 20) until ``done(feedback)``."""
    for seq in range(start, start + 20):
        feedback = _feedback(device)
        if done(feedback):
            return feedback
        device.write(answer(feedback, seq, (3000, 3000), ENABLE))
    raise AssertionError(f"not reached: {device.faults}")


def test_a_valve_in_fault_disables_every_valve_and_a_rearm_resets_it_on_a_rising_r_edge(
    bench: CanBench, channel: str
) -> None:
    device = _open(channel)
    words: list[int] = []
    rpdo = device.nodes[0].remote.rpdo[1]
    transmit = rpdo.transmit
    rpdo.transmit = lambda: (words.append(int(rpdo[0x6040].raw)), transmit())[1]  # type: ignore[method-assign]
    try:
        armed = _run(device, 5, (3000, 3000), ENABLE)
        with bench.lock:
            bench.valves[0].machine.fault()  # alpha's own monitor trips (a control deviation)
        faulted = _run(device, 2, (3000, 3000), ENABLE, start=10, feedback=armed)
        assert faulted.faults & FaultBit.VALVE_DRIVER
        assert device.faults[0] == "valve alpha (node 1): status word 0x0001 (FAULT_DISABLED)"
        assert bench.valve_states() == (ValveState.FAULT_DISABLED, ValveState.DISABLED)
        held = _run(device, 3, (3000, 3000), ENABLE, start=20, feedback=faulted)  # no re-arm: stays so
        assert bench.valve_states() == (ValveState.FAULT_DISABLED, ValveState.DISABLED)
        assert words[-1] == control_word(ValveState.DISABLED)  # R clear: the next R set is a rising edge
        rearmed = _run(device, 1, (3000, 3000), ENABLE | int(CommandFlag.REARM), start=30, feedback=held)
        assert words[-1] == control_word(ValveState.DISABLED, reset=True)
        assert bench.valve_states()[0] is ValveState.DISABLED  # out of FAULT (beta walks on: HOLD)
        assert rearmed.faults == 0
        _run(device, 3, (3000, 3000), ENABLE, start=40, feedback=rearmed)
        assert bench.valve_states() == (ValveState.ACTIVE, ValveState.ACTIVE)
        assert device.faults == ["valve alpha (node 1): status word 0x0001 (FAULT_DISABLED)"]
    finally:
        device.close()


def test_a_bench_gone_mid_run_faults_on_its_lost_heartbeats_not_after_the_pdo_validity(
    bench: CanBench, channel: str
) -> None:
    device = _open(channel, heartbeat_ms=200, pdo_validity_ms=600_000)  # lockstep's long validity
    try:
        armed = _run(device, 5, (3000, 3000), ENABLE)
        bench.close()  # its heartbeats and TPDOs stop (a bench killed, a cable pulled)
        device.write(answer(armed, 10, (3000, 3000), ENABLE))
        reading = None
        for _ in range(20):  # each read waits at most 5 s: a lost heartbeat (600 ms) must come first
            reading = device.read(5.0)
            if isinstance(reading, FeedbackFrame) and reading.faults:
                break
        assert isinstance(reading, FeedbackFrame) and reading.faults & FaultBit.VALVE_DRIVER, device.faults
        assert "valve alpha (node 1): heartbeat lost (none for 600 ms)" in device.faults
        assert "encoder beta (node 12): heartbeat lost (none for 600 ms)" in device.faults
    finally:
        device.close()


def test_a_malformed_tpdo_is_a_fault_naming_the_node(bench: CanBench, channel: str) -> None:
    device = _open(channel)
    injector = can.Bus(interface="virtual", channel=channel)
    try:
        armed = _run(device, 5, (3000, 3000), ENABLE)
        device.write(answer(armed, 10, (3000, 3000), ENABLE))
        injector.send(can.Message(arbitration_id=0x18B, data=b"\x01\x02", is_extended_id=False))
        faulted = _until(device, lambda f: bool(f.faults), armed, 11)
        assert faulted.faults & FaultBit.ENCODER
        assert "encoder alpha (node 11): TPDO1 0x18B of 2 bytes, its EDS maps 4" in device.faults
    finally:
        injector.shutdown()
        device.close()


@pytest.mark.parametrize(
    ("frames", "named"),
    [
        ([(0x18B, b"\x10\x00\x00\x00")], "encoder alpha (node 11): TPDO1 0x18B twice for SYNC "),
        ([(0x70C, b"\x00")], "encoder beta (node 12): boot-up: it reset (its configuration lost)"),
        (
            [(0x702, b"\x05"), (0x702, b"\x7f")],
            "valve beta (node 2): NMT state PRE-OPERATIONAL in its heartbeat",
        ),
        (
            [(0x601, bytes([0x2B, 0x40, 0x60, 0, 0x0F, 0, 0, 0]))],
            "valve alpha (node 1): frame 0x601 [2b 40 60",
        ),
    ],
    ids=["tpdo-twice", "boot-up", "back-to-pre-operational", "foreign-sdo-write"],
)
def test_a_frame_that_is_not_the_run_s_is_a_fault_naming_the_node(
    bench: CanBench, channel: str, frames: list[tuple[int, bytes]], named: str
) -> None:
    device = _open(channel)
    injector = can.Bus(interface="virtual", channel=channel)
    try:
        armed = _run(device, 5, (3000, 3000), ENABLE)
        device.write(answer(armed, 10, (3000, 3000), ENABLE))
        for cob_id, data in frames:
            injector.send(can.Message(arbitration_id=cob_id, data=data, is_extended_id=False))
        faulted = _until(device, lambda f: bool(f.faults), armed, 11)
        assert any(fault.startswith(named) for fault in device.faults), device.faults
        _run(device, 1, (3000, 3000), ENABLE, start=50, feedback=faulted)
        assert all(state is not ValveState.ACTIVE for state in bench.valve_states())
        assert [valve.spool for valve in bench.valves] == [0, 0]
    finally:
        injector.shutdown()
        device.close()


_UNTOLD = r"(no answer within 0\.3 s|its heartbeat lost for [0-9.]+ s: not asked)"


def test_make_safe_with_the_bench_gone_says_in_one_line_which_valves_were_not_told(
    bench: CanBench, channel: str, caplog: pytest.LogCaptureFixture
) -> None:
    device = _open(channel)  # sdo_timeout 0.3 s, heartbeats 1 s (consumers 3 s)
    try:
        _run(device, 5, (3000, 3000), ENABLE)
        bench.close()  # the emulated bench's process gone before the bridge shuts down
        caplog.set_level(logging.DEBUG, logger="canopen")
        line = device.make_safe()
    finally:
        device.close()
    assert line is not None and "\n" not in line
    assert re.fullmatch(
        rf"could not tell valve alpha \(node 1\) \({_UNTOLD}\), valve beta \(node 2\) \({_UNTOLD}\) "
        r"DISABLED by SDO \(0x6040\); each valve goes to its failsafe by itself: its receive deadline "
        r"0x1400:05 \(10 ms\) once its setpoints stop, its heartbeat consumer 0x1016 \(3000 ms\) once the "
        r"master's heartbeat stops",
        line,
    ), line
    assert not [r.getMessage() for r in caplog.records if "0x05040000" in r.getMessage()]  # no raw code
    assert any(
        f.startswith("valve beta (node 2): control word DISABLED by SDO not told (") for f in device.faults
    )


def test_make_safe_asks_no_valve_whose_heartbeat_is_lost(bench: CanBench, channel: str) -> None:
    device = _open(channel, heartbeat_ms=50)  # lost after 150 ms without one
    spy = can.Bus(interface="virtual", channel=channel)
    try:
        _run(device, 3, (3000, 3000), ENABLE)
        bench.close()
        time.sleep(0.5)  # every node's heartbeat lost
        while spy.recv(0) is not None:
            pass
        line = device.make_safe()
        sent = []
        while (message := spy.recv(0)) is not None:
            sent.append(message.arbitration_id)
    finally:
        spy.shutdown()
        device.close()
    assert 0x080 in sent  # the RPDOs and the SYNC went out
    assert 0x601 not in sent and 0x602 not in sent  # no SDO request waited for an answer
    assert line is not None and re.match(
        r"could not tell valve alpha \(node 1\) \(its heartbeat lost for [0-9.]+ s: not asked\), valve beta",
        line,
    ), line
