"""jog on drawn emulated benches in lockstep: the valves' and encoders' truths within the issue's tolerances,
inside the window; stopped at once on what it does not expect, the valves left disabled."""

from __future__ import annotations

import pytest
from drawn_benches import FaultyDevice, draw_bench
from smm_commissioning.emulated import LockstepDevice
from smm_commissioning.errors import MotionStopError
from smm_commissioning.host import BenchHost
from smm_commissioning.jog import JogConfig, run_jog
from smm_hw_bridge.protocol import CODE_MAX, FaultBit, StatusBit

SEEDS = [0, 1, 2, 3, 4, 5, 6, 12]
"""Drawn benches: every combination of reversed valve and down-counting encoder among them; in 6 beta starts
its jog off centre, its held oil carrying gravity's load (a torque that is not the valve's answer); in 12
beta's null bias (-236 codes) is past its overlap (204): code 0 opens it, so beta is jogged first."""


def jogged(device: LockstepDevice, config: JogConfig | None = None) -> tuple[BenchHost, tuple]:
    device.open()
    host = BenchHost(device)
    host.hold(100)
    return host, run_jog(host, config or JogConfig())


def disabled_at_the_end(device: LockstepDevice, host: BenchHost) -> bool:
    host.make_safe()
    last = host.feedback
    return last is not None and not last.status & StatusBit.ENABLED and device.board.output_codes() == (0, 0)


@pytest.mark.parametrize("seed", SEEDS)
def test_jog_finds_each_joints_truths_within_the_tolerances(seed: int) -> None:
    bench = draw_bench(seed)
    device = LockstepDevice(bench)
    host, results = jogged(device)
    window = JogConfig().window
    for r in results:
        j = r.joint
        full_scale = CODE_MAX / bench.full_scale_torque[j]  # codes per N m at a gain of 1
        assert r.direction == bench.direction[j]
        assert r.polarity == bench.valve_polarity[j]
        assert abs(r.deadband / bench.valve_deadband[j] - 1.0) < 0.15
        assert abs(r.null_bias - bench.valve_null_bias[j]) < 50.0
        assert abs(full_scale / r.gain_positive / bench.valve_gain_positive[j] - 1.0) < 0.05
        assert abs(full_scale / r.gain_negative / bench.valve_gain_negative[j] - 1.0) < 0.05
        assert 0.015 < r.lag < 0.03  # the emulated valve's rise: 21.7 ms
    # the window is around the start (q = 0): a cut pulse overshoots it by the hold's travel
    assert max(device.peak) < window + 0.05 < bench.plant.joint_limits[0]
    assert disabled_at_the_end(device, host)


def test_a_held_valve_open_at_code_0_has_its_joint_jogged_first() -> None:
    """Seed 12: beta drifts at code 0 during alpha's first pulses; beta is jogged, then alpha with beta at
    its null, and beta never reaches the window's edge."""
    device = LockstepDevice(draw_bench(12))
    _, results = jogged(device)
    assert [r.joint for r in results] == [0, 1]
    assert max(device.peak) < JogConfig().window


def test_both_valves_open_at_code_0_stop_the_jog() -> None:
    """Both nulls 100 codes past their overlaps, a window of 0.1 rad: alpha drifts while beta is jogged
    first."""
    device = LockstepDevice(draw_bench(12, valve_deadband=[200.0, 200.0], valve_null_bias=[300.0, -300.0]))
    with pytest.raises(MotionStopError, match=r"alpha drifted .* both valves open at code 0"):
        jogged(device, JogConfig(window=0.1))
    assert max(device.peak) < 0.1
    assert not device.board.status_enabled


def test_nothing_moves_before_the_first_enabled_pulse_and_the_valves_are_held_between() -> None:
    device = LockstepDevice(draw_bench(0))
    host, _ = jogged(device)
    record = host.record()
    enabled = record[:, -1]
    assert enabled[:100].sum() == 0  # the hold before the jog
    assert 0 < enabled.sum() < len(enabled)


def test_an_encoder_that_stops_counting_stops_the_jog_with_the_valves_disabled() -> None:
    device = FaultyDevice(draw_bench(1), frozen_encoder=0)
    with pytest.raises(
        MotionStopError, match=r"alpha stopped: its valve gives .* the encoder does not count"
    ):
        jogged(device)
    assert max(device.peak) < 0.3
    assert not device.board.status_enabled


def test_a_board_fault_during_the_jog_stops_it() -> None:
    device = LockstepDevice(draw_bench(2))
    device.open()
    host = BenchHost(device)
    host.hold(10)
    device.board.set_faults(int(FaultBit.OVERTEMP))
    with pytest.raises(MotionStopError, match="faults 0x0010"):
        run_jog(host, JogConfig())
    assert not device.board.status_enabled


def test_a_valve_that_gives_no_torque_stops_the_search() -> None:
    device = LockstepDevice(draw_bench(3, valve_deadband=[5000.0, 5000.0]))
    with pytest.raises(MotionStopError, match=r"gave no torque up to .2000 codes"):
        jogged(device, JogConfig(search_max=2000))
    assert not device.board.status_enabled


def test_a_joint_leaving_the_window_is_held_at_its_edge() -> None:
    """A tight window: pulses are cut at its edge, the joint never passes 1.5x of it."""
    bench = draw_bench(4)
    device = LockstepDevice(bench)
    try:
        _, results = jogged(device, JogConfig(window=0.03))
        assert any(p.cut for r in results for p in r.pulses)
    except MotionStopError as error:  # too tight to settle enough pulses: said so
        assert "too few settled pulses" in str(error)
    assert max(device.peak) < 0.045 + 0.01


@pytest.mark.parametrize(
    "field, value",
    [("window", 0.0), ("window", 0.6), ("velocity_limit", -1.0), ("pulse_ticks", 5), ("stair_levels", 0)],
)
def test_invalid_jog_settings_are_refused(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        JogConfig(**{field: value})  # type: ignore[arg-type]


def test_the_averaged_ticks_must_fit_in_a_pulse() -> None:
    with pytest.raises(ValueError, match="average_ticks"):
        JogConfig(pulse_ticks=50, average_ticks=50)
