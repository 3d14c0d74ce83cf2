"""Simulated plant: determinism, sensing, actuation, stops, disturbance, model error, input checks."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from smm_sim.plant import (
    PAPER_VALVE_RESPONSE_TIMES,
    PlantConfig,
    SimulatedPlant,
    disturbance_torque,
    eq46_disturbance,
    valve_time_constants_from_response_times,
)

from smm_dynamics import SMMParameters

DT = 1e-3


def _run(plant: SimulatedPlant, commands: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    measured, true = [], []
    for command in commands:
        measured.append(plant.measure().position)
        true.append(plant.ground_truth.position)
        plant.step(command, DT)
    return np.array(measured), np.array(true)


def _commands(steps: int) -> np.ndarray:
    t = np.arange(steps) * DT
    return np.column_stack((0.05 * np.sin(5.0 * t), 0.05 * np.cos(3.0 * t)))


def test_same_seed_gives_identical_runs_and_different_seeds_differ() -> None:
    config = PlantConfig(noise_std=(0.001, 0.002), disturbance="eq46", seed=7)
    commands = _commands(300)
    first = _run(SimulatedPlant(config), commands)
    second = _run(SimulatedPlant(config), commands)
    assert_array_equal(first[0], second[0])
    assert_array_equal(first[1], second[1])
    other = _run(SimulatedPlant(dataclasses.replace(config, seed=8)), commands)
    assert not np.array_equal(first[0], other[0])
    assert_array_equal(first[1], other[1])  # noise never touches the true state


def test_reset_replays_the_same_run() -> None:
    plant = SimulatedPlant(PlantConfig(noise_std=(0.001, 0.001), seed=3))
    commands = _commands(100)
    first = _run(plant, commands)
    plant.reset()
    assert plant.time_ns == 0
    second = _run(plant, commands)
    assert_array_equal(first[0], second[0])
    assert_array_equal(first[1], second[1])


def test_measure_is_repeatable_within_one_sample() -> None:
    plant = SimulatedPlant(PlantConfig(noise_std=(0.01, 0.01), seed=1))
    assert_array_equal(plant.measure().position, plant.measure().position)


def test_noise_statistics_match_configuration() -> None:
    std = (0.001, 0.003)
    plant = SimulatedPlant(PlantConfig(noise_std=std, seed=11))
    samples = []
    for _ in range(20000):  # at rest at q = 0: G(0) = 0, so the true state stays exactly 0
        samples.append(plant.measure().position)
        plant.step((0.0, 0.0), DT)
    noise = np.array(samples)
    assert_array_equal(plant.ground_truth.position, np.zeros(2))
    # Standard error of a sample std over n = 20000 is std / sqrt(2 n) = 0.5 %: 3 % is > 5 sigma.
    assert_allclose(noise.std(axis=0), std, rtol=0.03)
    assert np.all(np.abs(noise.mean(axis=0)) < 5.0 * np.asarray(std) / math.sqrt(noise.shape[0]))
    assert abs(np.corrcoef(noise.T)[0, 1]) < 0.05


@pytest.mark.parametrize("counts", [4096, 10000, 65536])
def test_encoder_quantisation_to_nearest_count(counts: int) -> None:
    quantum = 2.0 * math.pi / counts
    plant = SimulatedPlant(PlantConfig(encoder_counts_per_rev=counts))
    for position in ([0.123456, -0.654321], [1.0, 0.785], [quantum * 0.49, -quantum * 0.51]):
        plant.reset(position)
        measured = plant.measure().position
        counts_measured = measured / quantum
        assert_allclose(counts_measured, np.round(counts_measured), atol=1e-9)
        assert np.all(np.abs(measured - np.asarray(position)) <= quantum / 2.0 + 1e-15)
    plant.reset([quantum * 0.49, -quantum * 0.51])
    assert_allclose(plant.measure().position, [0.0, -quantum], atol=1e-15)


def test_no_quantisation_when_counts_is_zero() -> None:
    plant = SimulatedPlant(PlantConfig())
    plant.reset([0.123456789, -0.2])
    assert_array_equal(plant.measure().position, [0.123456789, -0.2])


def test_stops_hold_the_state_inside_and_zero_inward_velocity() -> None:
    limits = (0.5, 0.4)
    plant = SimulatedPlant(PlantConfig(joint_limits=limits))
    pushed_at_stop = 0
    for _ in range(1000):
        plant.step((2.0, -2.0), DT)
        truth = plant.ground_truth
        assert -limits[0] <= truth.position[0] <= limits[0]
        assert -limits[1] <= truth.position[1] <= limits[1]
        if truth.position[0] == limits[0]:
            assert truth.velocity[0] == 0.0  # inelastic: the inward component is removed
            pushed_at_stop += 1
        if truth.position[1] == -limits[1]:
            assert truth.velocity[1] == 0.0
    assert pushed_at_stop > 100
    assert_array_equal(plant.ground_truth.position, [limits[0], -limits[1]])
    for _ in range(20):  # pulling away leaves the stop at once
        plant.step((-2.0, 2.0), DT)
    truth = plant.ground_truth
    assert truth.position[0] < limits[0] and truth.velocity[0] < 0.0
    assert truth.position[1] > -limits[1] and truth.velocity[1] > 0.0


def test_saturation_clamps_the_applied_torque_and_effort_reports_it() -> None:
    plant = SimulatedPlant(PlantConfig(torque_limit=(2.0, 3.0)))
    plant.step((100.0, -100.0), DT)
    assert_array_equal(plant.measure().applied_torque, [2.0, -3.0])
    assert_array_equal(plant.ground_truth.applied_torque, [2.0, -3.0])
    assert_array_equal(plant.internals["commanded_torque"], [100.0, -100.0])
    plant.step((1.0, -0.5), DT)
    assert_array_equal(plant.measure().applied_torque, [1.0, -0.5])


def test_saturated_plant_moves_like_one_commanded_at_the_limit() -> None:
    saturated = SimulatedPlant(PlantConfig(torque_limit=(0.5, 0.5)))
    direct = SimulatedPlant(PlantConfig())
    for _ in range(100):
        saturated.step((50.0, -50.0), DT)
        direct.step((0.5, -0.5), DT)
    assert_array_equal(saturated.ground_truth.position, direct.ground_truth.position)


def test_torque_quantum_rounds_the_applied_torque_to_whole_codes_and_effort_reports_it() -> None:
    plant = SimulatedPlant(PlantConfig(torque_limit=(2.0, 2.0), torque_quantum=(0.25, 0.1)))
    plant.step((0.3, -0.26), DT)
    assert_allclose(plant.measure().applied_torque, [0.25, -0.3], rtol=0, atol=1e-15)
    plant.step((0.375, 100.0), DT)  # half a code rounds to even; saturation comes first
    assert_allclose(plant.measure().applied_torque, [0.5, 2.0], rtol=0, atol=1e-15)
    direct = SimulatedPlant(PlantConfig())
    direct.step((0.25, -0.3), DT)
    direct.step((0.5, 2.0), DT)
    quantised = SimulatedPlant(PlantConfig(torque_limit=(2.0, 2.0), torque_quantum=(0.25, 0.1)))
    quantised.step((0.3, -0.26), DT)
    quantised.step((0.375, 100.0), DT)
    assert_allclose(quantised.ground_truth.position, direct.ground_truth.position, rtol=0, atol=1e-15)


def test_effort_before_first_step_is_zero() -> None:
    assert_array_equal(SimulatedPlant(PlantConfig()).measure().applied_torque, [0.0, 0.0])


def test_valve_time_constants_from_paper_response_times() -> None:
    rise, fall = valve_time_constants_from_response_times(*PAPER_VALVE_RESPONSE_TIMES)
    assert_allclose((rise, fall), (0.050 / math.log(10.0), 0.025 / math.log(10.0)))
    assert_allclose(rise, 0.0217147, rtol=1e-5)
    rise63, _ = valve_time_constants_from_response_times(0.05, 0.025, reached_fraction=1.0 - math.exp(-1.0))
    assert_allclose(rise63, 0.05)


@pytest.mark.parametrize("substeps", [1, 3])
def test_valve_lag_first_order_rise_and_fall(substeps: int) -> None:
    rise, fall = 0.02, 0.008
    plant = SimulatedPlant(PlantConfig(valve_time_constants=(rise, fall), substeps=substeps))
    amplitude = 0.3
    steps = 200
    lag, effort = [], []
    for _ in range(steps):
        plant.step((amplitude, -amplitude), DT)
        lag.append(plant.internals["valve_torque"])
        effort.append(plant.measure().applied_torque)
    t_end = np.arange(1, steps + 1) * DT
    expected = amplitude * (1.0 - np.exp(-t_end / rise))
    assert_allclose(np.array(lag)[:, 0], expected, rtol=1e-9, atol=1e-12)
    assert_allclose(np.array(lag)[:, 1], -expected, rtol=1e-9, atol=1e-12)
    # The effort is the interval mean of the lag output: exact integral of the exponential.
    mean_first = amplitude * (1.0 - rise / DT * (1.0 - math.exp(-DT / rise)))
    assert_allclose(np.array(effort)[0, 0], mean_first, rtol=1e-9)
    # Time to 63.2 %: one time constant.
    crossing = t_end[np.argmax(np.array(lag)[:, 0] >= amplitude * (1.0 - math.exp(-1.0)))]
    assert abs(crossing - rise) <= DT * (1.0 + 1e-9)
    start = plant.internals["valve_torque"][0]
    for k in range(1, 31):
        plant.step((0.0, 0.0), DT)
        assert_allclose(plant.internals["valve_torque"][0], start * math.exp(-k * DT / fall), rtol=1e-9)


def test_valve_reversal_falls_then_rises() -> None:
    rise, fall = 0.02, 0.005
    plant = SimulatedPlant(PlantConfig(valve_time_constants=(rise, fall)))
    for _ in range(300):
        plant.step((1.0, 1.0), DT)
    start = plant.internals["valve_torque"][0]
    plant.step((-1.0, -1.0), DT)
    expected = -1.0 + (start + 1.0) * math.exp(-DT / fall)  # moving towards zero: fall constant
    assert_allclose(plant.internals["valve_torque"][0], expected, rtol=1e-12)


def test_eq46_disturbance_profile() -> None:
    assert eq46_disturbance(0.5) == (0.0, 0.0)
    assert eq46_disturbance(1.0) == (0.0, 0.0)
    value = 0.5 * math.cos(7.0 * 1.5)
    assert_allclose(eq46_disturbance(1.5), (-value, value), rtol=1e-15)
    assert_allclose(disturbance_torque("eq46", 2.0), (-0.5 * math.cos(14.0), 0.5 * math.cos(14.0)))
    assert disturbance_torque("none", 1.5) == (0.0, 0.0)
    with pytest.raises(ValueError, match="disturbance"):
        disturbance_torque("gusts", 1.5)


def test_eq46_disturbance_acts_on_the_plant_only_after_one_second() -> None:
    disturbed = SimulatedPlant(PlantConfig(disturbance="eq46"))
    quiet = SimulatedPlant(PlantConfig())
    for _ in range(1000):
        disturbed.step((0.0, 0.0), DT)
        quiet.step((0.0, 0.0), DT)
    assert_array_equal(disturbed.ground_truth.position, quiet.ground_truth.position)
    assert_array_equal(disturbed.ground_truth.disturbance_torque, [0.0, 0.0])
    for _ in range(50):
        disturbed.step((0.0, 0.0), DT)
        quiet.step((0.0, 0.0), DT)
    assert_allclose(disturbed.ground_truth.disturbance_torque, eq46_disturbance(1.05), rtol=1e-12)
    # tau_dist sits on the left of eq. 2: alpha gets -(-0.5 cos 7t) > 0 acceleration while cos 7t > 0.
    assert disturbed.ground_truth.position[0] > 0.0
    assert disturbed.ground_truth.position[1] < 0.0


def test_model_error_scales_the_inertias() -> None:
    params = SMMParameters()
    config = PlantConfig(params=params, inertia_scale=1.1)
    scaled = config.true_params
    for name in ("I11", "I22", "I44", "I55"):
        assert_allclose(getattr(scaled, name), 1.1 * getattr(params, name), rtol=1e-15)
    assert scaled.mass_lever == params.mass_lever
    nominal_plant = SimulatedPlant(PlantConfig(params=params))
    heavy_plant = SimulatedPlant(config)
    nominal_plant.step((0.01, 0.01), DT)
    heavy_plant.step((0.01, 0.01), DT)
    # From rest at q = 0 (M = diag(I55, I22), G = 0) the first displacement scales as 1 / inertia.
    ratio = nominal_plant.ground_truth.position / heavy_plant.ground_truth.position
    assert_allclose(ratio, [1.1, 1.1], rtol=1e-3)


@pytest.mark.parametrize(
    "command",
    [
        (math.nan, 0.0),
        (0.0, math.inf),
        (-math.inf, 1.0),
        (1.0, 2.0, 3.0),
        (1.0,),
        [[1.0, 2.0], [3.0, 4.0]],
        "ab",
        None,
    ],
)
def test_bad_torque_commands_are_rejected_and_leave_the_state_untouched(command: Any) -> None:
    plant = SimulatedPlant(PlantConfig())
    plant.step((0.2, -0.1), DT)
    before = plant.ground_truth
    with pytest.raises(ValueError, match="tau_command"):
        plant.step(command, DT)
    after = plant.ground_truth
    assert after.stamp_ns == before.stamp_ns
    assert_array_equal(after.position, before.position)
    assert_array_equal(after.velocity, before.velocity)
    assert_array_equal(after.applied_torque, before.applied_torque)


@pytest.mark.parametrize("dt", [0.0, -1e-3, math.nan, math.inf, 1e-11])
def test_bad_dt_rejected(dt: float) -> None:
    plant = SimulatedPlant(PlantConfig())
    with pytest.raises(ValueError, match="dt"):
        plant.step((0.0, 0.0), dt)
    assert plant.time_ns == 0


def test_time_is_exact_integer_nanoseconds() -> None:
    plant = SimulatedPlant(PlantConfig(substeps=3))
    for _ in range(5000):
        plant.step((0.0, 0.0), DT)
    assert plant.time_ns == 5_000_000_000
    assert plant.measure().stamp_ns == 5_000_000_000
    assert isinstance(plant.measure().stamp_ns, int)


def test_substeps_converge() -> None:
    def final_state(substeps: int) -> np.ndarray:
        # Hanging (gravity_sign -1) so the motion stays away from the stops, whose projection is
        # only first-order accurate in time.
        params = SMMParameters(gravity_sign=-1.0)
        plant = SimulatedPlant(PlantConfig(params=params, substeps=substeps, disturbance="eq46"))
        plant.reset([0.3, 0.2])
        for command in _commands(1500):
            plant.step(command, DT)
        truth = plant.ground_truth
        return np.concatenate((truth.position, truth.velocity))

    coarse, fine, finer = final_state(1), final_state(4), final_state(8)
    assert np.all(np.abs(finer[:2]) < 1.0)
    assert np.max(np.abs(fine - finer)) < np.max(np.abs(coarse - finer))
    assert_allclose(coarse, finer, atol=1e-5)


def test_internals_are_copies_of_shape_two() -> None:
    plant = SimulatedPlant(PlantConfig(noise_std=(0.001, 0.001)))
    plant.step((0.1, 0.1), DT)
    internals = plant.internals
    assert set(internals) >= {"commanded_torque", "applied_torque", "valve_torque", "measurement_noise"}
    for value in internals.values():
        assert value.shape == (2,)
    internals["applied_torque"][0] = 99.0
    assert plant.internals["applied_torque"][0] != 99.0


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("inertia_scale", 0.0),
        ("inertia_scale", math.nan),
        ("noise_std", (-0.001, 0.0)),
        ("noise_std", (0.001,)),
        ("encoder_counts_per_rev", -1),
        ("encoder_counts_per_rev", 1.5),
        ("seed", -1),
        ("disturbance", "wind"),
        ("joint_limits", (0.0, 1.0)),
        ("joint_limits", (1.3, 1.6)),
        ("torque_limit", (0.0, 1.0)),
        ("torque_limit", (math.nan, 1.0)),
        ("torque_quantum", (-0.1, 0.0)),
        ("torque_quantum", (math.inf, 0.0)),
        ("valve_time_constants", (0.0, 0.01)),
        ("valve_time_constants", (0.01,)),
        ("substeps", 0),
        ("control_period", 0.0),
        ("control_period", 1e-10),
        ("params", "not parameters"),
        # bools are not numbers here; a limit of exactly pi/2 is a singular pose
        ("inertia_scale", True),
        ("seed", True),
        ("substeps", True),
        ("control_period", True),
        ("control_period", "1 ms"),
        ("joint_limits", (math.pi / 2, 1.0)),
    ],
)
def test_config_validation_names_the_field(field: str, value: Any) -> None:
    with pytest.raises(ValueError, match=rf"^{field}\b"):
        PlantConfig(**{field: value})


def test_a_control_period_of_one_nanosecond_is_accepted() -> None:
    assert PlantConfig(control_period=1e-9).period_ns == 1


def test_reset_rejects_position_outside_stops() -> None:
    plant = SimulatedPlant(PlantConfig(joint_limits=(1.0, 1.0)))
    with pytest.raises(ValueError, match="position"):
        plant.reset([1.2, 0.0])
    with pytest.raises(ValueError, match="position"):
        plant.reset([math.nan, 0.0])


@pytest.mark.parametrize("joint", [0, 1])
def test_noise_and_torque_limit_on_one_joint_only(joint: int) -> None:
    """A per-joint setting that is off on the other joint acts on its own joint only (issue #16)."""
    std = [0.0, 0.0]
    std[joint] = 0.01
    noisy = SimulatedPlant(PlantConfig(noise_std=(std[0], std[1]), seed=5))
    limit = [math.inf, math.inf]
    limit[joint] = 1.0
    limited = SimulatedPlant(PlantConfig(torque_limit=(limit[0], limit[1])))
    for _ in range(5):
        noisy.step((0.1, -0.1), DT)
        limited.step((50.0, -50.0), DT)
    measured, truth = noisy.measure().position, noisy.ground_truth.position
    assert measured[joint] != truth[joint]
    assert abs(measured[1 - joint] - truth[1 - joint]) < 1e-6  # encoder quantisation only
    applied = limited.measure().applied_torque
    assert abs(applied[joint]) == 1.0
    assert abs(applied[1 - joint]) == 50.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((0.0, 0.02), r"^rise_time must be a finite number > 0 s, got 0.0"),
        ((math.nan, 0.02), r"^rise_time must be a finite number > 0 s, got nan"),
        ((0.05, -1.0), r"^fall_time must be a finite number > 0 s, got -1.0"),
        ((0.05, 0.02, 0.0), r"^reached_fraction must be in \(0, 1\), got 0.0"),
        ((0.05, 0.02, 1.0), r"^reached_fraction must be in \(0, 1\), got 1.0"),
        ((0.05, 0.02, 1.5), r"^reached_fraction must be in \(0, 1\), got 1.5"),
    ],
)
def test_valve_response_times_are_checked(args: tuple[float, ...], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        valve_time_constants_from_response_times(*args)
