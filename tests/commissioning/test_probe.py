"""probe on the emulated bench in lockstep: a healthy drawn bench passes, each fault is named, nothing
enabled."""

from __future__ import annotations

import math

import pytest
from drawn_benches import FaultyDevice, draw_bench
from smm_commissioning.emulated import LockstepDevice
from smm_commissioning.host import BenchHost
from smm_commissioning.probe import ProbeConfig, parse_pose, run_probe, zero_offset
from smm_hw_bridge.device import Device
from smm_hw_bridge.encoder import EncoderConfig
from smm_hw_bridge.protocol import FaultBit


def probe(device: Device, **config: object) -> tuple[BenchHost, object]:
    device.open()
    host = BenchHost(device)
    return host, run_probe(host, ProbeConfig(**config))  # type: ignore[arg-type]


def nothing_enabled(device: LockstepDevice, host: BenchHost) -> bool:
    return not host.enabled_ever and device.board.applied_log == [] and device.board.enabled_ticks == 0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_healthy_drawn_bench_passes_and_gives_the_counts_at_home(seed: int) -> None:
    bench = draw_bench(seed)
    device = LockstepDevice(bench)
    host, result = probe(device)
    assert result.passed, result.findings
    assert nothing_enabled(device, host)
    assert abs(result.supply_bar - bench.supply_pressure) < 0.05
    for j in range(2):  # home: the raw counts are the zero offset, give or take the encoder's noise
        assert abs(result.counts_at_pose[j] - bench.zero_offset[j]) < 20
        assert result.counts_std[j] > 0.5
        assert abs(result.rest_torque[j]) < 0.05


def test_low_supply_is_named_and_nothing_enabled() -> None:
    device = LockstepDevice(draw_bench(3, supply_pressure=3.0))
    host, result = probe(device)
    assert not result.passed
    assert any("SUPPLY_LOW" in f for f in result.findings)
    assert any(f.startswith("supply pressure 3.0") for f in result.findings)
    assert nothing_enabled(device, host)


def test_a_supply_below_the_steps_minimum_but_above_the_boards_is_named() -> None:
    device = LockstepDevice(draw_bench(3, supply_pressure=6.5))
    _, result = probe(device)
    assert result.findings == (result.findings[0],)
    assert "supply pressure 6.50 bar, below the 8 bar" in result.findings[0]


@pytest.mark.parametrize("joint", [0, 1])
def test_an_encoder_not_counting_is_named(joint: int) -> None:
    device = FaultyDevice(draw_bench(4), frozen_encoder=joint)
    host, result = probe(device)
    name = ("alpha", "beta")[joint]
    assert [f for f in result.findings if f.startswith(f"encoder {name} does not count")]
    assert len(result.findings) == 1
    assert nothing_enabled(device, host)


@pytest.mark.parametrize("channel", [1, 2])
def test_a_stuck_pressure_channel_is_named(channel: int) -> None:
    device = FaultyDevice(draw_bench(5), stuck_channel=channel, stuck_code=2050)
    host, result = probe(device)
    assert len(result.findings) == 1
    assert result.findings[0].startswith(f"load-pressure channel {channel} ")
    assert "is stuck at 2050" in result.findings[0]
    assert nothing_enabled(device, host)


def test_a_pressure_channel_at_its_rail_is_named() -> None:
    device = FaultyDevice(draw_bench(5), stuck_channel=2, stuck_code=4095)
    _, result = probe(device)
    assert len(result.findings) == 1 and "reads its rail" in result.findings[0]


def test_a_pressure_channel_off_zero_is_named() -> None:
    device = FaultyDevice(draw_bench(5, adc_noise=0.0), stuck_channel=1, stuck_code=2048 + 100)
    _, result = probe(device)
    assert len(result.findings) == 1 and "N m with the valves disabled" in result.findings[0]
    assert result.notes  # no A/D noise: a stuck channel cannot be told from a quiet one


def test_a_board_fault_is_named() -> None:
    device = LockstepDevice(draw_bench(6))
    device.open()
    device.board.set_faults(int(FaultBit.VALVE_DRIVER))
    host, result = probe(device)
    assert result.findings == (result.findings[0],) and "VALVE_DRIVER" in result.findings[0]
    assert nothing_enabled(device, host)


def test_quiet_encoders_are_noted_not_failed() -> None:
    device = LockstepDevice(draw_bench(7, plant={"noise_std": [0.0, 0.0]}))
    _, result = probe(device)
    assert result.passed and result.counts_span == (0, 0)
    assert any("jog's first motion" in note for note in result.notes)


def test_the_zero_of_a_confirmed_pose_follows_the_direction() -> None:
    encoder = EncoderConfig()
    quantum = float(encoder.quantum[0])
    assert zero_offset(1000, 100 * quantum, 1, encoder, 0) == 900
    assert zero_offset(1000, 100 * quantum, -1, encoder, 0) == 1100
    assert zero_offset(10, 100 * quantum, 1, encoder, 0) == (1 << 32) - 90


def test_pose_parsing() -> None:
    assert parse_pose("home") == (0.0, 0.0)
    assert parse_pose("0.1,-0.2") == (0.1, -0.2)
    for bad in ("0.1", "a,b", "nan,0", "0,inf", "1,2,3"):
        with pytest.raises(ValueError):
            parse_pose(bad)


@pytest.mark.parametrize(
    "field, value",
    [("ticks", 10), ("supply_min", math.nan), ("rest_torque_max", 0.0), ("pose", (0.0, math.inf))],
)
def test_invalid_probe_settings_are_refused(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        ProbeConfig(**{field: value})  # type: ignore[arg-type]
