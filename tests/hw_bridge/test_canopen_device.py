"""The CANopen master against the emulated bench on python-can's in-process ``virtual`` bus (lockstep)."""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest
from smm_bench_emulator.canopen_bench import CanBench, CanBenchConfig, eds_path
from smm_hw_bridge.canopen_config import CanopenConfig, bus_load, frame_bits, highest_rate_that_fits
from smm_hw_bridge.canopen_device import CanopenDevice, ConfigureError
from smm_hw_bridge.cia408 import ValveState
from smm_hw_bridge.core import BridgeConfig, BridgeCore
from smm_hw_bridge.device import open_device
from smm_hw_bridge.pressure import PressureConfig
from smm_hw_bridge.protocol import CommandFlag, FaultBit, FeedbackFrame, StatusBit
from smm_hw_bridge.transport import LinkConfig
from smm_hw_bridge.valve_output import ValveOutputConfig
from udp_bench import answer

_CHANNELS = itertools.count()
_FULL_SPOOL = BridgeConfig(valve=ValveOutputConfig(code_limit=(16384, 16384)))
TIMEOUT = 5.0  # generous: a missing answer fails, a slow machine does not


@pytest.fixture
def channel() -> str:
    return f"smm-test-{next(_CHANNELS)}"


@pytest.fixture
def bench(channel: str) -> Iterator[CanBench]:
    bench = CanBench(CanBenchConfig(), can.Bus(interface="virtual", channel=channel))
    yield bench
    bench.close()


def _config(**changes: object) -> CanopenConfig:
    values: dict[str, object] = {
        "interface": "virtual",
        "valve_eds": str(eds_path("valve_cia408.eds")),
        "encoder_eds": str(eds_path("encoder_cia406.eds")),
        "sdo_timeout": 0.3,
        "heartbeat_ms": 1000,  # consumers 3 s: a loaded machine's late heartbeat faults no test
    }
    values.update(changes)
    return CanopenConfig(**values)  # type: ignore[arg-type]


def _open(channel: str, **changes: object) -> CanopenDevice:
    device = CanopenDevice(_config(**changes), can.Bus(interface="virtual", channel=channel))
    device.open()
    return device


def _feedback(device: CanopenDevice) -> FeedbackFrame:
    reading = device.read(TIMEOUT)
    assert isinstance(reading, FeedbackFrame), reading
    return reading


def _run(
    device: CanopenDevice,
    cycles: int,
    codes: tuple[int, int],
    flags: int,
    *,
    start: int = 1,
    feedback: FeedbackFrame | None = None,
) -> FeedbackFrame:
    """``cycles`` commands, each answering the last feedback; the last feedback."""
    feedback = feedback or _feedback(device)
    for seq in range(start, start + cycles):
        device.write(answer(feedback, seq, codes, flags))
        feedback = _feedback(device)
    return feedback


def test_configure_reads_each_node_and_writes_the_settings(bench: CanBench, channel: str) -> None:
    device = _open(channel, period_us=2000, receive_deadline_ms=7, heartbeat_ms=500)
    try:
        assert [(n.name, n.device_type & 0xFFFF) for n in device.nodes] == [
            ("valve alpha (node 1)", 408),
            ("valve beta (node 2)", 408),
            ("encoder alpha (node 11)", 406),
            ("encoder beta (node 12)", 406),
        ]
        assert device.nodes[2].device_type >> 16 == 2  # the encoder's high word is kept, not compared
        assert device.nodes[0].identity[1] == 0x408
        assert device.found[0] == (
            "valve alpha (node 1): device type 0x00000198 (CiA 408), vendor 0x00000000, product 0x00000408, "
            "revision 0x00010000, serial 0x00000000"
        )
        assert device.found[3].startswith("encoder beta (node 12): device type 0x00020196 (CiA 406)")
        for valve in bench.valves:
            sdo = valve.node.sdo
            assert (sdo[0x6042].raw, sdo[0x6043].raw, sdo[0x1006].raw, sdo[0x1400][5].raw) == (1, 2, 2000, 7)
            assert sdo[0x1017].raw == 500
            assert sdo[0x1016][1].raw == (127 << 16) | 1500
        feedback = _feedback(device)
        assert feedback.seq == 1 and feedback.faults == 0
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
    finally:
        device.close()


def test_arming_walks_disabled_hold_active_and_the_setpoint_moves_the_plant(
    bench: CanBench, channel: str
) -> None:
    device = _open(channel)
    try:
        first = _feedback(device)
        device.write(answer(first, 1, (4000, -4000), int(CommandFlag.ENABLE)))
        held = _feedback(device)
        assert held.status & StatusBit.ENABLED == 0
        assert bench.valve_states() == (ValveState.HOLD, ValveState.HOLD)
        last = _run(device, 30, (4000, -4000), int(CommandFlag.ENABLE), start=2, feedback=held)
        assert bench.valve_states() == (ValveState.ACTIVE, ValveState.ACTIVE)
        assert last.status & StatusBit.ENABLED and last.output_codes == (4000, -4000)
        assert last.counts != first.counts  # the plant moved
        assert bench.syncs == last.seq  # lockstep: one SYNC per command
    finally:
        device.close()


@pytest.mark.parametrize("flags", [0, int(CommandFlag.ESTOP)], ids=["disarm", "estop"])
def test_disarm_and_estop_leave_every_valve_disabled(bench: CanBench, channel: str, flags: int) -> None:
    device = _open(channel)
    try:
        armed = _run(device, 5, (3000, 3000), int(CommandFlag.ENABLE))
        assert bench.valve_states() == (ValveState.ACTIVE, ValveState.ACTIVE)
        last = _run(
            device, 2, (3000, 3000), flags | int(CommandFlag.ENABLE) * (flags != 0), start=10, feedback=armed
        )
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
        assert last.output_codes == (0, 0)
        if flags:  # latched: enabled commands keep the valves DISABLED until a re-arm
            _run(device, 3, (3000, 3000), int(CommandFlag.ENABLE), start=20, feedback=last)
            assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
    finally:
        device.close()


def test_make_safe_disables_every_valve(bench: CanBench, channel: str) -> None:
    device = _open(channel)
    try:
        _run(device, 5, (3000, 3000), int(CommandFlag.ENABLE))
        device.make_safe()
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
    finally:
        device.close()


def test_a_code_beyond_full_spool_never_reaches_a_valve(bench: CanBench, channel: str) -> None:
    device = _open(channel)
    try:
        armed = _run(device, 5, (3000, 3000), int(CommandFlag.ENABLE))
        last = _run(device, 2, (16385, 0), int(CommandFlag.ENABLE), start=10, feedback=armed)
        assert device.dropped["code_limit"] == 2
        assert [v.setpoint for v in bench.valves] == [0, 0]
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
        assert last.output_codes == (0, 0)
    finally:
        device.close()


def test_setpoints_that_stop_fault_the_valve_by_itself_with_an_emcy(bench: CanBench, channel: str) -> None:
    device = _open(channel, receive_deadline_ms=3)
    try:
        armed = _run(device, 5, (3000, 3000), int(CommandFlag.ENABLE))
        bench.valves[1].node.rpdo[1].callbacks.clear()  # beta no longer hears its setpoints
        last = _run(device, 5, (3000, 3000), int(CommandFlag.ENABLE), start=10, feedback=armed)
        assert bench.valve_states()[1] is ValveState.FAULT_DISABLED
        assert bench.valves[1].spool == 0
        assert last.faults & FaultBit.VALVE_DRIVER
        assert any(f.startswith("valve beta (node 2): EMCY 0x8250") for f in device.faults), device.faults
        assert any("valve beta (node 2): status word 0x0001 (FAULT_DISABLED)" in f for f in device.faults)
        last = _run(device, 2, (3000, 3000), int(CommandFlag.ENABLE), start=20, feedback=last)
        assert bench.valve_states()[0] is ValveState.DISABLED  # any fault: every valve to DISABLED
        assert [valve.spool for valve in bench.valves] == [0, 0] and last.output_codes == (0, 0)
        assert not any("heartbeat" in f or "0x8130" in f for f in device.faults)  # the master's lived
        assert all(consumer.heard is not None and not consumer.lost for consumer in bench.consumers)
    finally:
        device.close()


def test_a_lost_master_heartbeat_faults_every_valve_by_itself_with_an_emcy(
    bench: CanBench, channel: str
) -> None:
    device = _open(channel, heartbeat_ms=200)  # the nodes' consumers: 600 ms
    try:
        armed = _run(device, 5, (3000, 3000), int(CommandFlag.ENABLE))
        assert bench.valve_states() == (ValveState.ACTIVE, ValveState.ACTIVE)
        deadline = time.monotonic() + TIMEOUT  # watching starts at the master's first heartbeat
        while not all(c.heard for c in bench.consumers) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert all(consumer.heard is not None for consumer in bench.consumers)
        bench.network.subscribers[0x700 + 127].clear()  # the master's heartbeat no longer reaches them
        faulted = _until_fault(device, armed, 10)
        assert faulted.faults & FaultBit.VALVE_DRIVER
        last = _run(device, 2, (3000, 3000), int(CommandFlag.ENABLE), start=20_000, feedback=faulted)
        assert bench.valve_states() == (ValveState.FAULT_DISABLED, ValveState.FAULT_DISABLED)
        assert [valve.spool for valve in bench.valves] == [0, 0] and last.output_codes == (0, 0)
        for name in ("valve alpha (node 1)", "valve beta (node 2)", "encoder beta (node 12)"):
            assert f"{name}: EMCY 0x8130 (error register 0x11)" in device.faults, device.faults
        assert last.faults & FaultBit.ENCODER
    finally:
        device.close()


def test_each_valve_sends_its_joints_load_pressure_and_the_bridge_reads_its_torque(
    bench: CanBench, channel: str
) -> None:
    pressure = PressureConfig(bar_per_code=(0.02, -0.015), zero_code=(1000.0, 3000.0))
    bridge = BridgeConfig(valve=_FULL_SPOOL.valve, pressure=pressure, supply_bar_per_code=0.005)
    device = CanopenDevice(
        _config(supply_bar=9.0), can.Bus(interface="virtual", channel=channel), bridge=bridge
    )
    device.open()
    try:
        last = _run(device, 30, (3000, -5000), int(CommandFlag.ENABLE))
        applied = bench.board.valves.applied
        load = bench.board.valves.load_pressure()
        assert applied[0] > 0.5 and applied[1] < -0.5  # the valves drive the joints
        sent = [int(valve.node.tpdo[1][0x6381].raw) for valve in bench.valves]
        assert sent == [round(bar / 0.01) for bar in load]  # 0x6381:01 in 0.01 bar units
        core = BridgeCore(bridge, host_session=7)  # the bridge's own path: bridge.pressure.* on the A/D
        assert core.on_feedback(last, time.monotonic_ns()) is last
        torque = core.measured_torque
        # quantised twice: 0.01 bar on the bus, bar_per_code on the A/D scale (x 1e5 Pa x 1.5e-5 m^3)
        for joint in range(2):
            step = (0.01 + abs(pressure.bar_per_code[joint])) * 1e5 * 1.5e-5
            assert torque[joint] == pytest.approx(applied[joint], abs=step)
        assert last.adc[0] == 1800  # canopen.supply_bar 9 bar / bridge.supply_bar_per_code 0.005
        assert core.supply_pressure_bar == pytest.approx(9.0)
    finally:
        device.close()


def test_a_missing_node_is_refused_naming_it_and_the_object(bench: CanBench, channel: str) -> None:
    with pytest.raises(ConfigureError, match=r"encoder beta \(node 13\): no answer to reading 0x1000:00"):
        _open(channel, encoder_node_ids=(11, 13))


def test_a_wrong_device_type_is_refused(bench: CanBench, channel: str) -> None:
    with pytest.raises(
        ConfigureError, match=r"valve alpha \(node 11\): device type 0x1000 = 0x00020196.*not CiA 408"
    ):
        _open(
            channel,
            valve_node_ids=(11, 2),
            encoder_node_ids=(1, 12),
            valve_eds=str(eds_path("encoder_cia406.eds")),
            encoder_eds=str(eds_path("valve_cia408.eds")),
        )


def test_a_pdo_mapping_that_differs_from_the_eds_is_refused(
    bench: CanBench, channel: str, tmp_path: Path
) -> None:
    text = eds_path("valve_cia408.eds").read_text()
    swapped = (
        text.replace("DefaultValue=0x63010110", "DefaultValue=0x63810110X")
        .replace("DefaultValue=0x63810110\n", "DefaultValue=0x63010110\n")
        .replace("0x63810110X", "0x63810110")
    )
    assert swapped != text
    user_eds = tmp_path / "valve.eds"
    user_eds.write_text(swapped)
    with pytest.raises(ConfigureError, match=r"valve alpha \(node 1\): PDO mapping 0x1A00 on the device is"):
        _open(channel, valve_eds=str(user_eds))


def test_configuration_is_refused_with_its_reason() -> None:
    with pytest.raises(ValueError, match="node ids must differ"):
        _config(valve_node_ids=(1, 11))
    with pytest.raises(ValueError, match="valve_eds must name one EDS file or one per joint"):
        _config(valve_eds="a, b, c")
    with pytest.raises(ValueError, match="bitrate"):
        _config(bitrate=2_000_000)
    with pytest.raises(ConfigureError, match="must name the devices' EDS files"):
        CanopenDevice(CanopenConfig(interface="virtual")).open()


@pytest.mark.parametrize("limit", [(16385, 16384), (16384, 32767)])
def test_a_code_limit_beyond_full_spool_is_refused_at_configure(
    bench: CanBench, channel: str, limit: tuple[int, int]
) -> None:
    bridge = BridgeConfig(valve=ValveOutputConfig(code_limit=limit))
    with pytest.raises(
        ConfigureError,
        match=rf"bridge.valve.code_limit \[{limit[0]}, {limit[1]}\] is above the valves' full scale 16384 "
        r"\(100 % spool, 0x6300:01\) on the CANopen link: set it to at most 16384",
    ):
        open_device(LinkConfig(transport="canopen"), _config(channel=channel), bridge)
    assert [valve.node.sdo[0x1017].raw for valve in bench.valves] == [0, 0]  # refused before any SDO


def test_link_transport_canopen_opens_the_bench_from_the_link_parameters(
    bench: CanBench, channel: str
) -> None:
    device = open_device(LinkConfig(transport="canopen"), _config(channel=channel), _FULL_SPOOL)
    try:
        assert isinstance(device, CanopenDevice)
        assert device.description.name == "canopen"
        assert _feedback(device).counts == bench.board.counts()
    finally:
        device.close()


def test_sync_on_enabled_steps_only_with_the_controller_and_still_disables_on_disarm(
    bench: CanBench, channel: str
) -> None:
    device = _open(channel, sync_on_enabled=True)
    try:
        first = _feedback(device)
        device.write(answer(first, 1, (0, 0), 0))
        # a disabled command after a disabled one: no SYNC, no step; the last feedback again after a while
        assert device.read(TIMEOUT) == first
        assert bench.syncs == 1
        armed = _run(device, 5, (2000, 2000), int(CommandFlag.ENABLE), start=2, feedback=first)
        assert bench.syncs == 6 and bench.valve_states() == (ValveState.ACTIVE, ValveState.ACTIVE)
        device.write(answer(armed, 10, (2000, 2000), 0))  # disarm: this one is SYNCed
        assert _feedback(device).output_codes == (0, 0)
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
        assert bench.syncs == 7
    finally:
        device.close()


def _until_fault(device: CanopenDevice, feedback: FeedbackFrame, start: int) -> FeedbackFrame:
    """Enabled cycles until a feedback carries a fault (at most 10000; each waits a little)."""
    for seq in range(start, start + 10_000):
        if feedback.faults:
            return feedback
        time.sleep(0.002)
        device.write(answer(feedback, seq, (3000, 3000), int(CommandFlag.ENABLE)))
        feedback = _feedback(device)
    raise AssertionError(f"no fault: {device.faults}")


def test_a_lost_heartbeat_is_a_fault_naming_the_node_and_every_valve_goes_disabled(
    bench: CanBench, channel: str
) -> None:
    device = _open(channel, heartbeat_ms=200)  # consumers 600 ms: no live node is that late
    try:
        armed = _run(device, 5, (3000, 3000), int(CommandFlag.ENABLE))
        assert bench.valve_states() == (ValveState.ACTIVE, ValveState.ACTIVE)
        bench.encoders[1].nmt.stop_heartbeat()
        faulted = _until_fault(device, armed, 10)
        assert faulted.faults & FaultBit.ENCODER
        assert device.faults == ["encoder beta (node 12): heartbeat lost (none for 600 ms)"]
        _run(device, 1, (3000, 3000), int(CommandFlag.ENABLE), start=5000, feedback=faulted)
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
    finally:
        device.close()


def test_a_tpdo_past_its_validity_is_a_fault_naming_the_node(
    bench: CanBench, channel: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    device = _open(channel, pdo_validity_ms=500)  # long: no other TPDO is ever that late
    try:
        armed = _run(device, 5, (3000, 3000), int(CommandFlag.ENABLE))
        monkeypatch.setattr(bench.encoders[1].tpdo[1], "transmit", lambda: None)
        device.write(answer(armed, 10, (3000, 3000), int(CommandFlag.ENABLE)))
        faulted = _feedback(device)
        assert faulted.faults & FaultBit.ENCODER and faulted.seq == armed.seq + 1
        assert device.faults == [
            f"encoder beta (node 12): TPDO1 of SYNC {faulted.seq} not arrived within 500 ms"
        ]
        device.write(answer(faulted, 11, (3000, 3000), int(CommandFlag.ENABLE)))
        assert _feedback(device).output_codes == (0, 0)  # the valves' TPDOs: after the SYNC was latched
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
    finally:
        device.close()


def test_the_bus_load_of_a_cycle_is_computed_from_the_mapped_pdos() -> None:
    payloads = [0, 4, 4, 6, 6, 4, 4]  # SYNC, valve RPDO1 x2, valve TPDO1 x2, encoder TPDO1 x2
    assert [frame_bits(size) for size in (0, 4, 6, 8)] == [52, 92, 112, 132]
    assert sum(frame_bits(size) for size in payloads) == 644
    assert bus_load(payloads, 1000, 1_000_000) == pytest.approx(0.644)
    assert highest_rate_that_fits(payloads, 500_000, 0.7) == 500


@pytest.mark.parametrize(
    ("bitrate", "limit", "fits"),
    [
        (1_000_000, 0.7, 1000),
        (250_000, 0.7, 250),
        (125_000, 0.7, 100),
        (200_000, 0.7, 200),
        (50_000, 0.7, None),
    ],
)
def test_the_highest_offered_rate_that_fits_includes_200_and_100_hz(
    bitrate: int, limit: float, fits: int | None
) -> None:
    payloads = [0, 4, 4, 6, 6, 4, 4]  # 644 bits a cycle
    assert highest_rate_that_fits(payloads, bitrate, limit) == fits
    if fits is not None:
        assert bus_load(payloads, fits, bitrate) <= limit


def test_a_bus_load_above_the_limit_is_refused_naming_the_rate_that_fits(
    bench: CanBench, channel: str
) -> None:
    with pytest.raises(
        ConfigureError,
        match=r"bus load 128.8 % at 1000 Hz and 500000 bit/s .*highest offered rate that fits is 500 Hz",
    ):
        _open(channel, bitrate=500_000)
    device = _open(channel, bitrate=500_000, period_us=2000)  # 500 Hz: 64.4 %, within 70 %
    device.close()
    with pytest.raises(  # 200 Hz on 125 kbit/s: 103 %; 100 Hz: 51.5 %
        ConfigureError,
        match=r"bus load 103.0 % at 200 Hz and 125000 bit/s .*highest offered rate that fits is 100 Hz",
    ):
        _open(channel, bitrate=125_000, period_us=5000, receive_deadline_ms=50)
    with pytest.raises(ConfigureError, match=r"64.4 % at 1000 Hz .* 50 %; .*fits is 500 Hz"):
        _open(channel, max_bus_load=0.5)  # a configured limit


def test_a_second_enabled_answer_to_one_feedback_steps_nothing(bench: CanBench, channel: str) -> None:
    device = _open(channel)
    try:
        armed = _run(device, 5, (2000, 2000), int(CommandFlag.ENABLE))
        device.write(answer(armed, 10, (2000, 2000), int(CommandFlag.ENABLE)))
        device.write(answer(armed, 11, (4000, 4000), int(CommandFlag.ENABLE)))  # answers it again
        after = _feedback(device)
        assert device.dropped["second_answer"] == 1
        assert after.seq == armed.seq + 1 and bench.syncs == after.seq
        assert after.output_codes == (2000, 2000)
    finally:
        device.close()


@pytest.mark.parametrize(
    ("changes", "why"),
    [
        ({"period_us": 5000, "receive_deadline_ms": 5}, "must be longer than the SYNC period"),
        ({"period_us": 10_000, "receive_deadline_ms": 9}, "must be longer than the SYNC period"),
        ({"sync_clock": True, "sync_on_enabled": True}, "exclude each other"),
    ],
)
def test_settings_a_real_time_bus_cannot_run_are_refused(changes: dict[str, object], why: str) -> None:
    with pytest.raises(ValueError, match=why):
        _config(**changes)


def test_in_real_time_the_reads_send_the_sync_and_a_command_sends_none(bench: CanBench, channel: str) -> None:
    device = _open(channel, sync_clock=True, period_us=5000, receive_deadline_ms=1000)
    try:
        assert device.clock is not None
        first = _feedback(device)
        syncs = bench.syncs
        for seq in range(1, 4):  # commands alone step nothing: no SYNC without the loop's read
            device.write(answer(first, seq, (0, 0), 0))
        assert bench.syncs == syncs
        seen = [_feedback(device) for _ in range(3)]  # the clock sends each SYNC when due
        assert [frame.seq for frame in seen] == [first.seq + 1, first.seq + 2, first.seq + 3]
        slots = [frame.tick // 5 for frame in seen]  # 5 ticks a period; a slot the loop missed is skipped
        assert all(frame.tick % 5 == 0 for frame in seen) and slots == sorted(set(slots))
        assert bench.syncs == syncs + 3 and device.clock.slot == slots[-1]
        assert bench.live_syncs == slots[-1] + 1  # the plant moved every slot, skipped ones too
    finally:
        device.close()


def test_configure_waits_for_nodes_that_come_up_after_the_bridge(channel: str) -> None:
    benches: list[CanBench] = []
    device = CanopenDevice(_config(), can.Bus(interface="virtual", channel=channel), boot_wait_s=60.0)
    late = threading.Timer(  # the emulator started after the bridge (smm-launch --record's order)
        0.5, lambda: benches.append(CanBench(CanBenchConfig(), can.Bus(interface="virtual", channel=channel)))
    )
    late.start()
    try:
        device.open()
        assert [line.split(":")[0] for line in device.found] == [
            "valve alpha (node 1)",
            "valve beta (node 2)",
            "encoder alpha (node 11)",
            "encoder beta (node 12)",
        ]
    finally:
        late.join()
        device.close()
        for bench in benches:
            bench.close()
