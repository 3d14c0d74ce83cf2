"""The plant's float fast path against a reference built on the array functions of smm_dynamics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal
from smm_sim.plant import PlantConfig, SimulatedPlant, disturbance_torque

from smm_dynamics import rk4_step

DT = 1e-3
FULL_CONFIG = PlantConfig(
    inertia_scale=1.1,
    noise_std=(2e-4, 1e-4),
    encoder_counts_per_rev=4096,
    seed=3,
    disturbance="eq46",
    joint_limits=(0.6, 0.5),
    torque_limit=(2.0, 1.5),
    valve_time_constants=(0.0217, 0.0109),
    substeps=3,
)


class _ReferencePlant:
    """The plant's true dynamics written with the array API (rk4_step) and numpy state."""

    def __init__(self, config: PlantConfig) -> None:
        self.config = config
        self.q = np.zeros(2)
        self.qd = np.zeros(2)
        self.valve = np.zeros(2)
        self.t_ns = 0

    def step(self, command: np.ndarray) -> np.ndarray:
        config = self.config
        limit = np.asarray(config.torque_limit)
        saturated = np.clip(command, -limit, limit)
        h = round(DT * 1e9) / 1e9 / config.substeps
        applied = np.zeros(2)
        for index in range(config.substeps):
            torque = self._valve(saturated, h)
            applied += torque
            dist = disturbance_torque(config.disturbance, self.t_ns / 1e9 + (index + 0.5) * h)
            params = config.true_params
            self.q, self.qd = rk4_step(self.q, self.qd, torque, h, params, tau_dist=np.array(dist))
            for joint, stop in enumerate(config.joint_limits):
                if self.q[joint] > stop:
                    self.q[joint], self.qd[joint] = stop, min(self.qd[joint], 0.0)
                elif self.q[joint] < -stop:
                    self.q[joint], self.qd[joint] = -stop, max(self.qd[joint], 0.0)
        self.t_ns += round(DT * 1e9)
        return applied / config.substeps

    def _valve(self, target: np.ndarray, h: float) -> np.ndarray:
        assert self.config.valve_time_constants is not None
        rise, fall = self.config.valve_time_constants
        mean = np.zeros(2)
        for joint in range(2):
            start, goal = self.valve[joint], target[joint]
            opening = start == 0.0 or (goal - start) * start > 0.0
            constant = rise if opening else fall
            decay = math.exp(-h / constant)
            self.valve[joint] = goal + (start - goal) * decay
            mean[joint] = goal + (start - goal) * (constant / h) * (1.0 - decay)
        return mean


def _commands(steps: int) -> list[tuple[float, float]]:
    return [(2.5 * math.sin(0.01 * k), -2.0 * math.cos(0.013 * k)) for k in range(steps)]


def test_true_state_matches_the_array_reference() -> None:
    """2 s with saturation, valve lag, sub-steps, eq. 46 and the stops hit: equal up to rounding."""
    plant = SimulatedPlant(FULL_CONFIG)
    reference = _ReferencePlant(FULL_CONFIG)
    hit_stop = False
    for command in _commands(2000):
        plant.step(command, DT)
        applied = reference.step(np.array(command))
        truth = plant.ground_truth
        assert_allclose(truth.position, reference.q, rtol=1e-12, atol=1e-12)
        assert_allclose(truth.velocity, reference.qd, rtol=1e-12, atol=1e-11)
        assert_allclose(truth.applied_torque, applied, rtol=1e-15, atol=1e-15)
        hit_stop |= bool(np.any(np.abs(truth.position) == np.asarray(FULL_CONFIG.joint_limits)))
    assert hit_stop, "the run must exercise the stops"


def test_sensor_draws_two_normals_per_sample_and_rounds_like_numpy() -> None:
    """Noise blocks give the same stream as two draws per sample; quantisation is np.round's."""
    plant = SimulatedPlant(FULL_CONFIG)
    generator = np.random.default_rng(FULL_CONFIG.seed)
    quantum = 2.0 * math.pi / FULL_CONFIG.encoder_counts_per_rev
    std = np.asarray(FULL_CONFIG.noise_std)
    for command in _commands(1500):  # more samples than one block of normals
        noise = generator.standard_normal(2) * std
        truth = plant.ground_truth.position
        assert_array_equal(plant.internals["measurement_noise"], noise)
        expected = np.round((truth + noise) / quantum) * quantum
        measured = plant.measure().position
        assert_array_equal(measured, expected)
        assert_array_equal(np.signbit(measured), np.signbit(expected))  # np.round keeps -0.0
        plant.step(command, DT)


def test_reset_restarts_the_noise_stream() -> None:
    plant = SimulatedPlant(FULL_CONFIG)
    first = []
    for command in _commands(30):
        first.append(plant.measure().position)
        plant.step(command, DT)
    plant.reset()
    for k, command in enumerate(_commands(30)):
        assert_array_equal(plant.measure().position, first[k])
        plant.step(command, DT)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), steps=st.integers(0, 40))
def test_float_accessors_equal_measure_and_ground_truth(seed: int, steps: int) -> None:
    plant = SimulatedPlant(PlantConfig(noise_std=(1e-3, 2e-3), seed=seed, disturbance="eq46"))
    for command in _commands(steps):
        plant.step(command, DT)
    sample, truth = plant.measure(), plant.ground_truth
    assert plant.measure_floats() == (*sample.position.tolist(), *sample.applied_torque.tolist())
    assert plant.state_floats == (*truth.position.tolist(), *truth.velocity.tolist())


def test_a_different_dt_object_is_validated_again() -> None:
    plant = SimulatedPlant(PlantConfig())
    plant.step((0.1, 0.1), DT)
    with pytest.raises(ValueError, match="dt"):
        plant.step((0.1, 0.1), 0.0)
    plant.step((0.1, 0.1), 2 * DT)
    assert plant.time_ns == 3_000_000
