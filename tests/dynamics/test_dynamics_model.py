"""The SMM rigid-body model against analytic references (SPEC section 1, paper eq. 1-2, Appendix A)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from smm_dynamics import (
    SMMParameters,
    coriolis_matrix,
    coriolis_vector,
    end_effector_position,
    forward_dynamics,
    friction_torque,
    gravity_vector,
    inverse_dynamics,
    kinetic_energy,
    mass_matrix,
    mass_matrix_gradient,
    mass_matrix_inverse,
    mass_matrix_time_derivative,
    potential_energy,
    rigid_body_terms,
    rk4_step,
    spin_angle,
    spin_angle_gradient,
    total_energy,
)

PARAMS = SMMParameters()
# Distinct inertias so that a swapped I11/I22/I44 in the code cannot go unnoticed.
DISTINCT = SMMParameters(I11=0.05, I22=0.08, I44=0.11, I55=0.07, viscous_friction=(0.3, 0.2))
BOX = 1.2
angles = st.floats(-BOX, BOX, allow_nan=False, allow_subnormal=True)
rates = st.floats(-5.0, 5.0, allow_nan=False, allow_subnormal=True)
torques = st.floats(-10.0, 10.0, allow_nan=False, allow_subnormal=True)
joint = st.tuples(angles, angles).map(np.array)
velocity = st.tuples(rates, rates).map(np.array)
torque = st.tuples(torques, torques).map(np.array)


def printed_mass_matrix(q: NDArray[np.float64], p: SMMParameters) -> NDArray[np.float64]:
    """M(q) typed in literally from Appendix A (tan/sec form)."""
    alpha, beta = q
    sec2 = 1.0 / np.cos(alpha) ** 2
    d = np.tan(alpha) ** 2 + np.cos(beta) ** 2
    m11 = p.I44 + sec2 * np.cos(beta) ** 2 * d**-2 * (p.I55 * sec2 - p.I11 * d)
    m12 = np.tan(alpha) * np.sin(beta) * np.cos(beta) * d**-2 * (p.I55 * sec2 - 0.5 * p.I11 * d)
    m22 = p.I22 + p.I55 * np.tan(alpha) ** 2 * np.sin(beta) ** 2 * d**-2
    return np.array([[m11, m12], [m12, m22]])


def central_difference(function, q: NDArray[np.float64], step: float = 1e-6) -> NDArray[np.float64]:  # type: ignore[no-untyped-def]
    """Derivatives d function / d q_k stacked on a new leading axis."""
    columns = []
    for k in range(2):
        offset = np.zeros(2)
        offset[k] = step
        columns.append((np.asarray(function(q + offset)) - np.asarray(function(q - offset))) / (2 * step))
    return np.stack(columns)


def test_mass_matrix_at_origin_is_diag_i55_i22() -> None:
    np.testing.assert_allclose(
        mass_matrix(np.zeros(2), PARAMS), np.diag([PARAMS.I55, PARAMS.I22]), rtol=1e-15
    )
    # In general M11(0) = I44 - I11 + I55: the I11 and I44 terms cancel only because I11 = I44 (SPEC 1).
    expected = np.diag([DISTINCT.I44 - DISTINCT.I11 + DISTINCT.I55, DISTINCT.I22])
    np.testing.assert_allclose(mass_matrix(np.zeros(2), DISTINCT), expected, rtol=1e-15)


@given(joint)
def test_mass_matrix_equals_the_printed_formula(q: NDArray[np.float64]) -> None:
    np.testing.assert_allclose(
        mass_matrix(q, DISTINCT), printed_mass_matrix(q, DISTINCT), rtol=1e-12, atol=1e-14
    )


@given(joint)
def test_i55_enters_as_spin_inertia_times_gradient_outer_product(q: NDArray[np.float64]) -> None:
    heavier = SMMParameters(I55=DISTINCT.I55 + 1.0, I11=DISTINCT.I11, I22=DISTINCT.I22, I44=DISTINCT.I44)
    gradient = spin_angle_gradient(q)
    np.testing.assert_allclose(
        mass_matrix(q, heavier) - mass_matrix(q, DISTINCT), np.outer(gradient, gradient), atol=1e-12
    )


def test_mass_matrix_is_symmetric_positive_definite_on_a_grid() -> None:
    grid = np.linspace(-BOX, BOX, 49)
    q = np.stack(np.meshgrid(grid, grid, indexing="ij"), axis=-1).reshape(-1, 2)
    mass = mass_matrix(q, PARAMS)
    np.testing.assert_array_equal(mass, np.swapaxes(mass, -1, -2))
    assert np.linalg.eigvalsh(mass).min() >= 0.065


@given(joint)
def test_mass_matrix_min_eigenvalue_bound(q: NDArray[np.float64]) -> None:
    mass = mass_matrix(q, PARAMS)
    assert mass[0, 1] == mass[1, 0]
    assert np.linalg.eigvalsh(mass).min() >= 0.065


@given(joint)
def test_mass_matrix_inverse_inverts(q: NDArray[np.float64]) -> None:
    np.testing.assert_allclose(
        mass_matrix_inverse(q, DISTINCT) @ mass_matrix(q, DISTINCT), np.eye(2), atol=1e-12
    )


@given(joint)
def test_mass_matrix_gradient_matches_finite_difference(q: NDArray[np.float64]) -> None:
    numeric = central_difference(lambda x: mass_matrix(x, DISTINCT), q)
    np.testing.assert_allclose(mass_matrix_gradient(q, DISTINCT), numeric, atol=1e-8)


@given(joint, velocity)
def test_dm_dt_minus_two_c_is_skew_symmetric(q: NDArray[np.float64], qd: NDArray[np.float64]) -> None:
    n = mass_matrix_time_derivative(q, qd, DISTINCT) - 2.0 * coriolis_matrix(q, qd, DISTINCT)
    scale = 1.0 + np.abs(n).max()
    np.testing.assert_allclose(n + n.T, np.zeros((2, 2)), atol=1e-12 * scale)


@given(joint, velocity)
def test_coriolis_vector_is_christoffel_form(q: NDArray[np.float64], qd: NDArray[np.float64]) -> None:
    # (C q')_k = sum_ij (dM_kj/dq_i - 0.5 dM_ij/dq_k) q'_i q'_j, with dM/dq by finite differences.
    gradient = central_difference(lambda x: mass_matrix(x, DISTINCT), q)  # [i, k, j] = dM_kj/dq_i
    expected = np.einsum("ikj,i,j->k", gradient, qd, qd) - 0.5 * np.einsum("kij,i,j->k", gradient, qd, qd)
    np.testing.assert_allclose(coriolis_vector(q, qd, DISTINCT), expected, atol=1e-7)
    np.testing.assert_allclose(
        coriolis_matrix(q, qd, DISTINCT) @ qd, coriolis_vector(q, qd, DISTINCT), atol=1e-12
    )


def test_dm_dt_matches_finite_difference_along_a_trajectory() -> None:
    dt = 1e-3
    states = [(np.array([0.2, -0.3]), np.array([0.9, 0.7]))]
    for _ in range(300):
        states.append(rk4_step(*states[-1], np.array([0.05, -0.02]), dt, DISTINCT))
    for (q_prev, _), (q, qd), (q_next, _) in zip(states, states[1:], states[2:], strict=False):
        numeric = (mass_matrix(q_next, DISTINCT) - mass_matrix(q_prev, DISTINCT)) / (2 * dt)
        np.testing.assert_allclose(mass_matrix_time_derivative(q, qd, DISTINCT), numeric, atol=1e-6)
        n = mass_matrix_time_derivative(q, qd, DISTINCT) - 2.0 * coriolis_matrix(q, qd, DISTINCT)
        np.testing.assert_allclose(n + n.T, np.zeros((2, 2)), atol=1e-12)


@pytest.mark.parametrize(
    ("params", "friction", "q0", "qd0"),
    [
        (SMMParameters(mass_lever=0.0, viscous_friction=(0.0, 0.0)), True, (0.3, -0.4), (0.3, 0.25)),
        (dataclasses.replace(DISTINCT, gravity_sign=-1.0), False, (0.3, -0.4), (0.3, 0.25)),
        (SMMParameters(gravity_sign=-1.0), False, (0.3, -0.4), (0.4, 0.5)),
    ],
    ids=["no-gravity-no-friction", "friction-switched-off", "hanging-with-gravity"],
)
def test_energy_is_conserved_without_input_and_friction(
    params: SMMParameters, friction: bool, q0: tuple[float, float], qd0: tuple[float, float]
) -> None:
    q, qd = np.array(q0), np.array(qd0)
    initial = float(total_energy(q, qd, params))
    drift = 0.0
    for _ in range(2000):  # 2 s at 1 ms
        q, qd = rk4_step(q, qd, np.zeros(2), 1e-3, params, friction=friction)
        drift = max(drift, abs(float(total_energy(q, qd, params)) - initial) / abs(initial))
    assert drift < 1e-9
    assert np.abs(qd).max() > 0.1  # it really moved


def test_friction_dissipates_energy_at_the_viscous_rate() -> None:
    params = SMMParameters(mass_lever=0.0)
    q, qd = np.array([0.1, 0.2]), np.array([0.5, -0.4])
    dt = 1e-4
    q1, qd1 = rk4_step(q, qd, np.zeros(2), dt, params)
    rate = (float(total_energy(q1, qd1, params)) - float(total_energy(q, qd, params))) / dt
    expected = -float(qd @ friction_torque(qd, params))
    assert rate == pytest.approx(expected, rel=1e-3)


@settings(max_examples=200)
@given(joint, velocity, torque, torque)
def test_inverse_dynamics_inverts_forward_dynamics(
    q: NDArray[np.float64], qd: NDArray[np.float64], tau: NDArray[np.float64], dist: NDArray[np.float64]
) -> None:
    for friction in (True, False):
        qdd = forward_dynamics(q, qd, tau, DISTINCT, tau_dist=dist, friction=friction)
        recovered = inverse_dynamics(q, qd, qdd, DISTINCT, tau_dist=dist, friction=friction)
        np.testing.assert_allclose(recovered, tau, atol=1e-10)


@given(joint, velocity, velocity)
def test_inverse_dynamics_is_eq2(
    q: NDArray[np.float64], qd: NDArray[np.float64], qdd: NDArray[np.float64]
) -> None:
    expected = (
        mass_matrix(q, DISTINCT) @ qdd
        + coriolis_matrix(q, qd, DISTINCT) @ qd
        + gravity_vector(q, DISTINCT)
        + np.asarray(DISTINCT.viscous_friction) * qd
    )
    np.testing.assert_allclose(inverse_dynamics(q, qd, qdd, DISTINCT), expected, atol=1e-12)


def test_disturbance_acts_as_negative_torque() -> None:
    q, qd, tau, dist = (
        np.array([0.4, 0.3]),
        np.array([0.2, -0.1]),
        np.array([1.0, 2.0]),
        np.array([0.3, -0.5]),
    )
    np.testing.assert_allclose(
        forward_dynamics(q, qd, tau, DISTINCT, tau_dist=dist), forward_dynamics(q, qd, tau - dist, DISTINCT)
    )


def test_rigid_body_terms_match_the_array_functions() -> None:
    q, qd = np.array([0.4, -0.7]), np.array([1.3, -0.6])
    m11, m12, m22, c1, c2, g1, g2 = rigid_body_terms(0.4, -0.7, 1.3, -0.6, DISTINCT)
    mass = mass_matrix(q, DISTINCT)
    np.testing.assert_allclose([m11, m12, m22], [mass[0, 0], mass[0, 1], mass[1, 1]], rtol=1e-15)
    np.testing.assert_allclose([c1, c2], coriolis_vector(q, qd, DISTINCT), rtol=1e-15)
    np.testing.assert_allclose([g1, g2], gravity_vector(q, DISTINCT), rtol=1e-15)


@given(joint)
def test_gravity_vector_is_gradient_of_potential(q: NDArray[np.float64]) -> None:
    for params in (PARAMS, SMMParameters(gravity_sign=-1.0)):
        numeric = central_difference(lambda x, p=params: potential_energy(x, p), q)
        np.testing.assert_allclose(gravity_vector(q, params), numeric, atol=1e-9)


def test_potential_is_highest_upright_for_positive_gravity_sign() -> None:
    upright = float(potential_energy(np.zeros(2), PARAMS))
    assert upright == pytest.approx(PARAMS.mass_lever * PARAMS.gravity)
    assert float(potential_energy(np.array([0.0, 0.5]), PARAMS)) < upright
    hanging = SMMParameters(gravity_sign=-1.0)
    assert float(potential_energy(np.array([0.0, 0.5]), hanging)) > float(
        potential_energy(np.zeros(2), hanging)
    )


def test_friction_torque_is_viscous() -> None:
    np.testing.assert_allclose(friction_torque(np.array([2.0, -3.0]), DISTINCT), [0.6, -0.6])


@given(joint)
def test_spin_angle_gradient_matches_finite_difference(q: NDArray[np.float64]) -> None:
    numeric = central_difference(spin_angle, q)
    np.testing.assert_allclose(spin_angle_gradient(q), numeric, atol=1e-8)


def test_spin_angle_formula() -> None:
    q = np.array([0.7, -1.0])
    assert float(spin_angle(q)) == pytest.approx(np.arctan2(np.tan(0.7), np.cos(-1.0)), rel=1e-15)
    assert float(spin_angle(np.zeros(2))) == 0.0


def rotation_matrix_eq1(alpha: float, beta: float) -> NDArray[np.float64]:
    """R_{X0 Z1 Z0} of eq. 1, with theta computed here from its definition."""
    theta = np.arctan2(np.tan(alpha), np.cos(beta))
    ca, sa, cb, sb, ct, st_ = (
        np.cos(alpha),
        np.sin(alpha),
        np.cos(beta),
        np.sin(beta),
        np.cos(theta),
        np.sin(theta),
    )
    return np.array(
        [
            [ca * ct + sa * cb * st_, sa * ct - ca * cb * st_, sb * st_],
            [ca * st_ - sa * cb * ct, sa * st_ + ca * cb * ct, -sb * ct],
            [-sa * sb, ca * sb, cb],
        ]
    )


@given(joint)
def test_end_effector_is_l_times_third_column_of_eq1(q: NDArray[np.float64]) -> None:
    params = SMMParameters(link_length=0.25)
    rotation = rotation_matrix_eq1(*q)
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(2 + 1), atol=1e-12)
    position = end_effector_position(q, params)
    np.testing.assert_allclose(position, 0.25 * rotation[:, 2], atol=1e-14)
    assert np.linalg.norm(position) == pytest.approx(0.25, rel=1e-13)


def test_end_effector_points_up_at_rest() -> None:
    np.testing.assert_allclose(end_effector_position(np.zeros(2), PARAMS), [0.0, 0.0, PARAMS.link_length])


def test_rk4_is_fourth_order() -> None:
    q0, qd0, tau = np.array([0.3, 0.2]), np.array([1.0, -0.8]), np.array([0.1, 0.4])

    def integrate(steps: int) -> NDArray[np.float64]:
        q, qd = q0, qd0
        for _ in range(steps):
            q, qd = rk4_step(q, qd, tau, 0.2 / steps, DISTINCT)
        return np.concatenate([q, qd])

    reference = integrate(640)
    coarse_error = np.abs(integrate(20) - reference).max()
    fine_error = np.abs(integrate(40) - reference).max()
    assert 12.0 < coarse_error / fine_error < 20.0


@pytest.mark.parametrize("dt", [0.0, -1e-3, float("nan"), float("inf")])
def test_rk4_rejects_bad_step(dt: float) -> None:
    with pytest.raises(ValueError, match="dt"):
        rk4_step(np.zeros(2), np.zeros(2), np.zeros(2), dt, PARAMS)


@pytest.mark.parametrize("bad", [np.zeros(3), np.zeros((4, 3)), np.float64(0.0), np.zeros((2, 1))])
def test_joint_arrays_of_wrong_shape_are_rejected(bad: NDArray[np.float64]) -> None:
    with pytest.raises(ValueError, match="q must have shape"):
        mass_matrix(bad, PARAMS)
    with pytest.raises(ValueError, match="tau must have shape"):
        forward_dynamics(np.zeros(2), np.zeros(2), bad, PARAMS)
    with pytest.raises(ValueError, match="qd must have shape"):
        coriolis_vector(np.zeros(2), bad, PARAMS)


def test_batch_evaluation_equals_per_sample_evaluation() -> None:
    rng = np.random.default_rng(7)
    q = rng.uniform(-BOX, BOX, (3, 4, 2))
    qd = rng.uniform(-3, 3, (3, 4, 2))
    tau = rng.uniform(-2, 2, (3, 4, 2))
    dist = rng.uniform(-1, 1, (3, 4, 2))
    batched = {
        "spin_angle": spin_angle(q),
        "spin_angle_gradient": spin_angle_gradient(q),
        "mass_matrix": mass_matrix(q, DISTINCT),
        "mass_matrix_inverse": mass_matrix_inverse(q, DISTINCT),
        "mass_matrix_gradient": mass_matrix_gradient(q, DISTINCT),
        "mass_matrix_time_derivative": mass_matrix_time_derivative(q, qd, DISTINCT),
        "coriolis_matrix": coriolis_matrix(q, qd, DISTINCT),
        "coriolis_vector": coriolis_vector(q, qd, DISTINCT),
        "gravity_vector": gravity_vector(q, DISTINCT),
        "friction_torque": friction_torque(qd, DISTINCT),
        "kinetic_energy": kinetic_energy(q, qd, DISTINCT),
        "forward_dynamics": forward_dynamics(q, qd, tau, DISTINCT, tau_dist=dist),
        "inverse_dynamics": inverse_dynamics(q, qd, tau, DISTINCT, tau_dist=dist),
        "end_effector_position": end_effector_position(q, DISTINCT),
        "rk4_q": rk4_step(q, qd, tau, 1e-3, DISTINCT, tau_dist=dist)[0],
        "rk4_qd": rk4_step(q, qd, tau, 1e-3, DISTINCT, tau_dist=dist)[1],
    }
    for index in np.ndindex(3, 4):
        single = {
            "spin_angle": spin_angle(q[index]),
            "spin_angle_gradient": spin_angle_gradient(q[index]),
            "mass_matrix": mass_matrix(q[index], DISTINCT),
            "mass_matrix_inverse": mass_matrix_inverse(q[index], DISTINCT),
            "mass_matrix_gradient": mass_matrix_gradient(q[index], DISTINCT),
            "mass_matrix_time_derivative": mass_matrix_time_derivative(q[index], qd[index], DISTINCT),
            "coriolis_matrix": coriolis_matrix(q[index], qd[index], DISTINCT),
            "coriolis_vector": coriolis_vector(q[index], qd[index], DISTINCT),
            "gravity_vector": gravity_vector(q[index], DISTINCT),
            "friction_torque": friction_torque(qd[index], DISTINCT),
            "kinetic_energy": kinetic_energy(q[index], qd[index], DISTINCT),
            "forward_dynamics": forward_dynamics(
                q[index], qd[index], tau[index], DISTINCT, tau_dist=dist[index]
            ),
            "inverse_dynamics": inverse_dynamics(
                q[index], qd[index], tau[index], DISTINCT, tau_dist=dist[index]
            ),
            "end_effector_position": end_effector_position(q[index], DISTINCT),
            "rk4_q": rk4_step(q[index], qd[index], tau[index], 1e-3, DISTINCT, tau_dist=dist[index])[0],
            "rk4_qd": rk4_step(q[index], qd[index], tau[index], 1e-3, DISTINCT, tau_dist=dist[index])[1],
        }
        for name, value in single.items():
            assert batched[name][index].shape == np.shape(value), name
            np.testing.assert_allclose(batched[name][index], value, rtol=1e-13, atol=1e-15, err_msg=name)


def test_single_sample_broadcasts_against_a_batch() -> None:
    q = np.array([0.3, -0.2])
    qd = np.array([[1.0, 0.5], [-0.4, 0.2], [0.0, 0.0]])
    batched = coriolis_vector(q, qd, DISTINCT)
    assert batched.shape == (3, 2)
    for row, velocity_row in zip(batched, qd, strict=True):
        np.testing.assert_allclose(row, coriolis_vector(q, velocity_row, DISTINCT), rtol=1e-14)
    accelerations = forward_dynamics(q, qd, np.zeros(2), DISTINCT)
    np.testing.assert_allclose(
        accelerations[1], forward_dynamics(q, qd[1], np.zeros(2), DISTINCT), rtol=1e-14
    )


def test_single_sample_outputs_have_documented_shapes() -> None:
    q, qd = np.array([0.3, -0.2]), np.array([0.1, 0.2])
    assert mass_matrix(q, PARAMS).shape == (2, 2)
    assert coriolis_matrix(q, qd, PARAMS).shape == (2, 2)
    assert mass_matrix_gradient(q, PARAMS).shape == (2, 2, 2)
    assert gravity_vector(q, PARAMS).shape == (2,)
    assert end_effector_position(q, PARAMS).shape == (3,)
    assert spin_angle(q).shape == ()
    assert kinetic_energy(q, qd, PARAMS).shape == ()
    assert [a.shape for a in rk4_step(q, qd, qd, 1e-3, PARAMS)] == [(2,), (2,)]
    assert mass_matrix([0.3, -0.2], PARAMS).shape == (2, 2)  # plain sequences are accepted
