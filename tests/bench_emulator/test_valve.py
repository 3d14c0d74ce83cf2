"""The emulated valve: polarity, null bias, overlap, gain per direction, hydraulic lock, load pressure."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from smm_bench_emulator.bench import BenchSettings
from smm_bench_emulator.board import BoardConfig, BoardCore
from smm_bench_emulator.valve import HydraulicValves
from smm_dynamics.model import gravity_vector
from smm_hw_bridge.pressure import PASCAL_PER_BAR, PressureConfig, measured_torque
from smm_hw_bridge.protocol import CODE_MAX, CommandFlag, CommandFrame, decode_feedback, encode
from smm_sim.plant import PlantConfig, SimulatedPlant

HOST = 0x00C0FFEE
LAG = (0.0217, 0.0109)
PLANT = PlantConfig(encoder_counts_per_rev=1 << 20, valve_time_constants=LAG)
MINUTE_TICKS = 60_000


def test_polarity_null_bias_and_gain_per_direction_set_the_torque() -> None:
    settings = BenchSettings(
        valve_polarity=(-1, 1),
        valve_null_bias=(200.0, -300.0),
        valve_gain_positive=(0.8, 0.8),
        valve_gain_negative=(1.2, 1.2),
        full_scale_torque=(10.0, 4.0),
    )
    valves = HydraulicValves(settings, None)
    assert valves.target((200, -300), 10.0) == (0.0, 0.0)  # the null is at the bias
    alpha, beta = valves.target((200 + 1000, -300 + 1000), 10.0)
    assert alpha == pytest.approx(-1000 / CODE_MAX * 10.0 * 1.2)  # reversed: q negative, negative gain
    assert beta == pytest.approx(1000 / CODE_MAX * 4.0 * 0.8)
    alpha, beta = valves.target((200 - 1000, -300 - 1000), 2.5)  # a quarter of the supply: half the torque
    assert alpha == pytest.approx(1000 / CODE_MAX * 10.0 * 0.8 * 0.5)
    assert beta == pytest.approx(-1000 / CODE_MAX * 4.0 * 1.2 * 0.5)


def test_the_overlap_holds_the_joint_and_outside_it_the_valve_drives() -> None:
    settings = BenchSettings(valve_deadband=(800.0, 800.0), valve_null_bias=(200.0, 200.0))
    valves = HydraulicValves(settings, None)
    assert valves.drive((999, -599), True, 10.0, 1e-3) == (0.0, 0.0)
    assert valves.locked == (True, True)  # |spool| = 799 < 800 on both
    alpha, beta = valves.drive((1100, -700), True, 10.0, 1e-3)
    assert valves.locked == (False, False)
    assert (alpha, beta) == pytest.approx((100 / CODE_MAX * 10.0, -100 / CODE_MAX * 10.0))
    valves.drive((1100, -700), False, 10.0, 1e-3)
    assert valves.locked == (True, True)  # disabled: fail-safe, the oil is trapped


def test_the_lock_takes_over_at_the_torque_it_had_and_resists_as_a_spring_and_damper() -> None:
    settings = BenchSettings(
        lock_stiffness=(1000.0, 1000.0), lock_damping=(5.0, 5.0), lock_leakage=(0.0, 0.0)
    )
    valves = HydraulicValves(settings, None)
    valves.drive((3276, 0), True, 10.0, 1e-3)
    assert valves.applied[0] == pytest.approx(1.0, rel=1e-3)
    trapped = valves.target((3276, 0), 10.0)[0]
    assert valves.drive((0, 0), False, 10.0, 1e-3) == (trapped, 0.0)  # no jump
    valves.follow((0.001, -0.002), (0.5, 0.0), 1e-3)
    alpha, beta = valves.drive((0, 0), False, 10.0, 1e-3)
    assert alpha == pytest.approx(trapped - 1000.0 * 0.001 - 5.0 * 0.5)
    assert beta == pytest.approx(1000.0 * 0.002)


def test_with_the_defaults_the_board_drives_the_plant_exactly_as_the_simulator_with_its_lag() -> None:
    core = BoardCore(BoardConfig(plant=PLANT, adc_noise=0.0))
    sim = SimulatedPlant(PLANT)
    host = _Host(core)
    rng = np.random.default_rng(4)
    for _ in range(600):
        codes = (int(rng.integers(-8000, 8000)), int(rng.integers(-8000, 8000)))
        host.send(codes)
        core.tick_lockstep()
        sim.step(np.array(codes) / CODE_MAX * 10.0, 1e-3)
        assert core.plant.state_floats == sim.state_floats
    assert max(abs(v) for v in sim.state_floats) > 0.01  # it moved


class _Host:
    """Sends enabled commands answering the board's last feedback."""

    def __init__(self, core: BoardCore) -> None:
        self.core = core
        self.seq = 1
        if core.last_feedback is None:
            core.start()
        self._send(0, (0, 0), 5)  # a disabled frame locks the board to this host

    def send(self, codes: tuple[int, int], validity: int = 5) -> None:
        self.seq += 1
        self._send(int(CommandFlag.ENABLE), codes, validity)

    def _send(self, flags: int, codes: tuple[int, int], validity: int) -> None:
        fb = self.core.last_feedback
        assert fb is not None
        frame = CommandFrame(HOST, self.seq, self.core.session, fb.seq, fb.tick, flags, validity, codes)
        assert self.core.receive(encode(frame)) is not None


def _held_minute(
    config: BoardConfig, beta: float, codes: tuple[int, int] | None
) -> tuple[float, HydraulicValves]:
    """Beta after 60 s of emulated time from rest at ``beta``, disabled (None) or enabled at ``codes``."""
    plant = SimulatedPlant(dataclasses.replace(config.plant, valve_time_constants=None))
    plant.reset([0.0, beta])
    valves = HydraulicValves(config, config.plant.valve_time_constants)
    for _ in range(MINUTE_TICKS):
        valves.move(plant, codes or (0, 0), codes is not None, config.supply_pressure)
    return plant.state_floats[1], valves


def _stated_drift(settings: BenchSettings, load: float, seconds: float) -> float:
    """The oil column's give under ``load`` N m plus the leakage drift over ``seconds`` (rad), beta."""
    return load / settings.lock_stiffness[1] + settings.lock_leakage[1] * load * seconds


@pytest.mark.parametrize("codes", [None, (200, 200)], ids=["disabled", "enabled at null inside the overlap"])
def test_held_beta_drifts_by_the_stated_leakage_over_a_minute(codes: tuple[int, int] | None) -> None:
    config = BoardConfig(
        plant=PLANT, adc_noise=0.0, valve_deadband=(800.0, 800.0), valve_null_bias=(200.0, 200.0)
    )
    start = 0.5
    load = abs(float(gravity_vector([0.0, start], PLANT.params)[1]))
    end, valves = _held_minute(config, start, codes)
    drift = abs(end - start)
    worst_load = abs(float(gravity_vector([0.0, PLANT.joint_limits[1]], PLANT.params)[1]))
    assert drift < _stated_drift(config, worst_load, 60.0)  # the stated bound: the worst load in the range
    assert drift == pytest.approx(_stated_drift(config, load, 60.0), rel=0.05)  # and the model's own figure
    assert end > start  # it gives way to gravity (away from upright), slowly
    assert valves.locked == (True, True)
    # the transducers read the load the oil holds: gravity's torque at beta
    pressure = valves.load_pressure()[1] * PASCAL_PER_BAR * config.lever_arm_area[1]
    assert pressure == pytest.approx(float(gravity_vector([0.0, end], PLANT.params)[1]), rel=1e-3)


def test_without_leakage_a_held_joint_gives_only_the_oil_column() -> None:
    config = BoardConfig(plant=PLANT, adc_noise=0.0, lock_leakage=(0.0, 0.0))
    load = abs(float(gravity_vector([0.0, 0.5], PLANT.params)[1]))
    end, _ = _held_minute(config, 0.5, None)
    assert abs(end - 0.5) == pytest.approx(load / config.lock_stiffness[1], rel=0.02)


def test_load_pressure_is_the_valve_torque_over_lever_arm_times_area_on_channels_1_and_2() -> None:
    config = BoardConfig(
        plant=dataclasses.replace(PLANT, valve_time_constants=None),
        adc_noise=0.0,
        lever_arm_area=(1e-5, 2e-5),
        load_zero_code=(2000.0, 2100.0),
        load_bar_per_code=(0.01, 0.02),
    )
    core = BoardCore(config)
    host = _Host(core)
    core.tick_lockstep()
    host.send((6553, -16384))
    fb = decode_feedback(core.tick_lockstep())
    torque = core.valve_torque()
    assert core.valves.applied == torque
    bar = (torque[0] / 1e-5 / 1e5, torque[1] / 2e-5 / 1e5)  # 2 N m on 1e-5 m^3: 2 bar
    assert bar == pytest.approx((2.0, -2.5), rel=1e-4)
    assert fb.adc[1:3] == (round(2000 + bar[0] / 0.01), round(2100 + bar[1] / 0.02))
    assert fb.adc[3] == 2048


def test_the_bridge_calibration_of_the_same_truths_reads_the_torque_within_one_code() -> None:
    config = BoardConfig(plant=PLANT, adc_noise=0.0, lever_arm_area=(1e-5, 2e-5))
    calibration = PressureConfig(bar_per_code=config.load_bar_per_code, lever_arm_area=(1e-5, 2e-5))
    core = BoardCore(config)
    host = _Host(core)
    core.tick_lockstep()
    for codes in ((6553, -16384), (-3000, 250), (0, 0)):
        host.send(codes)
        adc = decode_feedback(core.tick_lockstep()).adc
        one_code = [config.load_bar_per_code[j] * PASCAL_PER_BAR * config.lever_arm_area[j] for j in range(2)]
        error = np.subtract(measured_torque(adc, calibration), core.valves.applied)
        assert np.all(np.abs(error) <= np.multiply(one_code, 0.5 + 1e-9))


def test_load_pressure_noise_is_the_a_d_noise() -> None:
    core = BoardCore(BoardConfig(plant=PLANT, adc_noise=3.0, seed=5))
    samples = np.array([decode_feedback(core.tick_realtime()).adc for _ in range(4000)], dtype=np.float64)
    assert samples[:, 1].mean() == pytest.approx(2048.0, abs=0.3)  # at rest, nothing held: zero load
    assert samples[:, 1].std() == pytest.approx(3.0, rel=0.1)


def test_at_defaults_a_disabled_joint_no_longer_falls_onto_its_stop() -> None:
    # the torque-source valve dropped beta from 0.01 rad to its 1.3 rad stop within 5 s
    core = BoardCore(BoardConfig(plant=PLANT, adc_noise=0.0))
    core.plant.reset([0.0, 0.01])
    for _ in range(5000):
        core.tick_realtime()
    assert abs(core.plant.state_floats[1] - 0.01) < 1e-4


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"valve_polarity": (0, 1)}, "valve_polarity"),
        ({"valve_null_bias": (40000.0, 0.0)}, "valve_null_bias"),
        ({"valve_gain_negative": (0.0, 1.0)}, "valve_gain_negative"),
        ({"lock_stiffness": (1e6, 2000.0)}, "lock_stiffness"),
        ({"lock_damping": (16.0, 500.0)}, "lock_damping"),
        ({"lever_arm_area": (math.nan, 1e-5)}, "lever_arm_area"),
    ],
)
def test_invalid_valve_settings_are_rejected_with_their_name(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        BoardConfig(**kwargs)  # type: ignore[arg-type]
