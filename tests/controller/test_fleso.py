"""FLESO (eq. 19-23): pole placement, discretisation, disturbance estimation on the plant model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_controller.fleso import FLESO, FLESOConfig, observer_gains
from smm_controller.fuzzy_batch import evaluate_system
from smm_controller.rules import fleso_bandwidth_system

from smm_dynamics import SMMParameters, gravity_vector, inverse_dynamics, mass_matrix, rk4_step

DT = 0.001
PARAMS = SMMParameters()


def error_matrix(bandwidth: float) -> np.ndarray:
    l1, l2, l3 = observer_gains(bandwidth)
    return np.array([[-l1, 1.0, 0.0], [-l2, 0.0, 1.0], [-l3, 0.0, 0.0]])


@pytest.mark.parametrize("w", [9.0, 20.0, 31.0, 48.0, 500.0])
def test_error_dynamics_have_a_triple_pole_at_minus_w(w: float) -> None:
    coefficients = np.poly(error_matrix(w))
    assert_allclose(coefficients, [1.0, 3 * w, 3 * w**2, w**3], rtol=1e-12)
    eigenvalues = np.linalg.eigvals(error_matrix(w))
    assert_allclose(eigenvalues.real, -w, rtol=1e-3)  # a triple root, so eigenvalues are ill-conditioned


@pytest.mark.parametrize("w", [9.0, 31.0, 48.0])
def test_discrete_predictor_corrector_error_dynamics(w: float) -> None:
    """Error propagation (I - dt L C)(I + dt A) is stable and tends to I + dt (A - L C)."""
    a = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    gains = np.array(observer_gains(w))[:, None]
    c = np.array([[1.0, 0.0, 0.0]])
    for dt in (1e-3, 1e-5):
        discrete = (np.eye(3) - dt * gains @ c) @ (np.eye(3) + dt * a)
        assert np.max(np.abs(np.linalg.eigvals(discrete))) < 1.0
        assert_allclose((discrete - np.eye(3)) / dt, error_matrix(w), atol=w**3 * dt * 1.01)


def test_first_step_initialises_at_the_measurement() -> None:
    fleso = FLESO(None, PARAMS)
    assert_allclose(fleso.step([0.2, -0.1], [1.0, 1.0], DT), [0.0, 0.0])
    internals = fleso.internals
    assert_allclose(internals["x1_hat"], [0.2, -0.1])
    assert_allclose(internals["x2_hat"], [0.0, 0.0])
    assert_allclose(internals["x3_hat"], [0.0, 0.0])


def test_one_step_follows_the_documented_update() -> None:
    """Prediction with the model and the applied torque, then correction with l(w) times the innovation."""
    config = FLESOConfig()
    fleso = FLESO(config, PARAMS)
    fleso.step([0.1, 0.2], [0.0, 0.0], DT)
    y, tau = np.array([0.1003, 0.1998]), np.array([0.05, -0.02])
    xi = fleso.step(y, tau, DT)
    q0 = np.array([0.1, 0.2])
    m = mass_matrix(q0, PARAMS)
    accel = np.linalg.solve(m, tau - gravity_vector(q0, PARAMS))  # x2^ = 0, so C x2^ = 0
    innovation = y - q0
    s = np.clip(np.array(config.k_s1) * innovation + np.array(config.k_s2) * innovation / DT, -1, 1)
    system = fleso_bandwidth_system()
    w = np.array(config.w0) + np.array(config.k_w) * np.array([evaluate_system(system, (v,))[0] for v in s])
    l1, l2, l3 = observer_gains(w)
    internals = fleso.internals
    assert_allclose(internals["bandwidth"], w, rtol=1e-13)
    assert_allclose(internals["fuzzy_input"], s, rtol=1e-13)
    assert_allclose(internals["x1_hat"], q0 + DT * l1 * innovation, rtol=1e-13)
    assert_allclose(internals["x2_hat"], DT * accel + DT * l2 * innovation, rtol=1e-12)
    assert_allclose(internals["x3_hat"], DT * l3 * innovation, rtol=1e-12)
    assert_allclose(xi, -mass_matrix(y, PARAMS) @ internals["x3_hat"], rtol=1e-12)


def test_bandwidth_floor() -> None:
    config = FLESOConfig(w0=(2.0, 2.0), k_w=(50.0, 50.0), k_s1=(1e6, 1e6), w_min=(1.5, 0.5))
    fleso = FLESO(config, PARAMS)
    fleso.step([0.0, 0.0], [0.0, 0.0], DT)
    fleso.step([0.01, -0.01], [0.0, 0.0], DT)  # |s| saturates: rule NB/PB -> S, f(w) near -0.8
    assert_allclose(fleso.internals["bandwidth"], [1.5, 0.5])


def hold_position(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """A stabilising PD around q = 0 with gravity compensation (the FLESO only observes)."""
    return -5.0 * q - 1.0 * qd + gravity_vector(q, PARAMS)


@pytest.mark.parametrize("disturbance", [(0.2, -0.15), (-0.05, 0.1)])
def test_estimates_a_constant_external_disturbance(disturbance: tuple[float, float]) -> None:
    """On the exact model with tau_dist constant, xi~ converges to tau_dist + friction (total disturbance)."""
    fleso = FLESO(None, PARAMS)
    q, qd = np.array([0.1, -0.1]), np.zeros(2)
    tau_applied = np.zeros(2)
    for _ in range(4000):
        xi = fleso.step(q, tau_applied, DT)
        tau_applied = hold_position(q, qd)
        q, qd = rk4_step(q, qd, tau_applied, DT, PARAMS, tau_dist=np.array(disturbance))
    friction = np.array(PARAMS.viscous_friction) * qd
    assert_allclose(xi, np.array(disturbance) + friction, atol=1e-9)
    assert_allclose(fleso.internals["x2_hat"], qd, atol=1e-9)


def test_estimates_a_model_error() -> None:
    """A plant with 10 % larger inertias moving sinusoidally: xi~ tracks (M_plant - M) q'' + ..."""
    plant = dataclasses.replace(
        PARAMS,
        I11=PARAMS.I11 * 1.1,
        I22=PARAMS.I22 * 1.1,
        I44=PARAMS.I44 * 1.1,
        I55=PARAMS.I55 * 1.1,
        viscous_friction=(0.0, 0.0),
    )
    fleso = FLESO(None, PARAMS)
    q, qd = np.zeros(2), np.zeros(2)
    tau_applied = np.zeros(2)
    errors, totals = [], []
    for k in range(5000):
        xi = fleso.step(q, tau_applied, DT)
        tau_applied = np.array([0.3 * np.sin(2.0 * k * DT), 0.2 * np.cos(3.0 * k * DT)]) + hold_position(
            q, qd
        )
        # Total disturbance by eq. 5: what the nominal model misses of the applied torque.
        qdd = (rk4_step(q, qd, tau_applied, 1e-7, plant)[1] - qd) / 1e-7
        if k > 3000:
            total = tau_applied - inverse_dynamics(q, qd, qdd, PARAMS, friction=False)
            totals.append(total)
            errors.append(total - xi)
        q, qd = rk4_step(q, qd, tau_applied, DT, plant)
    largest = np.max(np.abs(totals), axis=0)
    assert np.all(largest > 1e-3)
    assert np.all(np.max(np.abs(errors), axis=0) < 0.35 * largest)


@pytest.mark.parametrize("slope", [0.3, -1.2])
def test_velocity_of_a_noise_free_ramp_is_its_slope(slope: float) -> None:
    """y = (c t, 0) with tau = 0: on beta = 0 the model's M is constant and C = G = 0, so the total
    disturbance is 0 and the LESO's fixed point is x2^ = (c, 0), x3^ = 0 (analytic reference)."""
    fleso = FLESO(None, PARAMS)
    for k in range(3000):
        fleso.step([slope * k * DT, 0.0], [0.0, 0.0], DT)
    assert fleso.velocity_floats() == tuple(fleso.internals["x2_hat"])
    assert_allclose(fleso.velocity_floats(), (slope, 0.0), rtol=0, atol=1e-9)
    assert_allclose(fleso.internals["x3_hat"], (0.0, 0.0), atol=1e-7)


_JOINT = st.floats(-1.0, 1.0, allow_nan=False)
_TORQUE = st.floats(-200.0, 200.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(
    samples=st.lists(st.tuples(_JOINT, _JOINT, _TORQUE, _TORQUE), min_size=2, max_size=12),
    prepared=st.lists(st.booleans(), min_size=12, max_size=12),
    new_model_at=st.integers(0, 12),
)
def test_prepare_ahead_changes_no_step(
    samples: list[tuple[float, float, float, float]], prepared: list[bool], new_model_at: int
) -> None:
    """Steps with prepare() between some of them equal those without, bit for bit, across a model change.

    Given the next position (the TD's), right or wrong, or none.
    """
    other = dataclasses.replace(PARAMS, I55=2.0 * PARAMS.I55)
    plain, ahead = FLESO(None, PARAMS), FLESO(None, PARAMS)
    for k, (y0, y1, tau0, tau1) in enumerate(samples):
        if prepared[k]:
            ahead.prepare(((y0, y1), (y1, y0), None)[k % 3])
        if k == new_model_at:  # a new nominal model after prepare(): its terms are not taken
            for observer in (plain, ahead):
                observer.reconfigure(observer.config, params=other)
        assert ahead.step_floats(y0, y1, tau0, tau1, DT) == plain.step_floats(y0, y1, tau0, tau1, DT)
        assert ahead.velocity_floats() == plain.velocity_floats()
