"""Coulomb friction and torque offset: F(q') = f_v q' + f_c sign(q') + offset in every path of the model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from numpy.typing import NDArray

from smm_dynamics import (
    SMMParameters,
    coriolis_vector,
    forward_dynamics,
    forward_dynamics_floats,
    friction_torque,
    gravity_vector,
    inverse_dynamics,
    mass_matrix,
    rk4_step,
    rk4_step_floats,
)

VISCOUS = (0.3, 0.2)
COULOMB = (0.7, 0.45)
OFFSET = (-0.25, 0.4)
FRICTIONAL = SMMParameters(
    I11=0.05,
    I22=0.08,
    I44=0.11,
    I55=0.07,
    viscous_friction=VISCOUS,
    coulomb_friction=COULOMB,
    torque_offset=OFFSET,
)

angles = st.floats(-1.2, 1.2)
rates = st.floats(-6.0, 6.0)
torques = st.floats(-5.0, 5.0)


def _analytic_friction(qd: tuple[float, float]) -> NDArray[np.float64]:
    sign = np.array([1.0 if v > 0 else -1.0 if v < 0 else 0.0 for v in qd])
    return np.asarray(np.asarray(VISCOUS) * np.asarray(qd) + np.asarray(COULOMB) * sign + np.asarray(OFFSET))


def test_defaults_are_zero() -> None:
    params = SMMParameters()
    assert params.coulomb_friction == (0.0, 0.0)
    assert params.torque_offset == (0.0, 0.0)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("coulomb_friction", (-0.1, 0.0), r"^coulomb_friction must be >= 0"),
        ("coulomb_friction", (0.1, float("nan")), r"^coulomb_friction must be a real number"),
        ("coulomb_friction", (0.1,), r"^coulomb_friction must be a tuple"),
        ("torque_offset", (0.0, float("inf")), r"^torque_offset must be finite"),
        ("torque_offset", [0.0, 0.0], r"^torque_offset must be a tuple"),
    ],
)
def test_invalid_values_name_the_field(field: str, value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        SMMParameters(**{field: value})  # type: ignore[arg-type]


def test_negative_offset_is_allowed() -> None:
    assert SMMParameters(torque_offset=(-1.0, 2.0)).torque_offset == (-1.0, 2.0)


@pytest.mark.parametrize("qd", [(0.0, 0.0), (0.5, -0.2), (-1e-9, 3.0), (0.0, -2.0)])
def test_friction_torque_is_viscous_plus_coulomb_sign_plus_offset(qd: tuple[float, float]) -> None:
    assert_allclose(friction_torque(np.array(qd), FRICTIONAL), _analytic_friction(qd), rtol=0, atol=1e-15)


def test_sign_at_zero_velocity_is_zero() -> None:
    """At rest only the offset remains: no Coulomb torque without a direction of motion."""
    assert_allclose(friction_torque(np.zeros(2), FRICTIONAL), OFFSET, rtol=0, atol=0)
    batch = friction_torque(np.zeros((3, 2)), FRICTIONAL)
    assert_allclose(batch, np.tile(OFFSET, (3, 1)), rtol=0, atol=0)


@settings(max_examples=100, deadline=None)
@given(a=angles, b=angles, ad=rates, bd=rates, add=rates, bdd=rates)
def test_inverse_dynamics_adds_the_analytic_friction(
    *, a: float, b: float, ad: float, bd: float, add: float, bdd: float
) -> None:
    q, qd, qdd = np.array([a, b]), np.array([ad, bd]), np.array([add, bdd])
    expected = (
        mass_matrix(q, FRICTIONAL) @ qdd
        + coriolis_vector(q, qd, FRICTIONAL)
        + gravity_vector(q, FRICTIONAL)
        + _analytic_friction((ad, bd))
    )
    assert_allclose(inverse_dynamics(q, qd, qdd, FRICTIONAL), expected, rtol=1e-12, atol=1e-12)
    # The batch path gives the same as the single-sample path.
    batch = inverse_dynamics(np.tile(q, (2, 1)), np.tile(qd, (2, 1)), np.tile(qdd, (2, 1)), FRICTIONAL)
    assert_allclose(batch, np.tile(expected, (2, 1)), rtol=1e-12, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(a=angles, b=angles, ad=rates, bd=rates, ta=torques, tb=torques)
def test_forward_and_inverse_dynamics_are_consistent(
    *, a: float, b: float, ad: float, bd: float, ta: float, tb: float
) -> None:
    q, qd, tau = np.array([a, b]), np.array([ad, bd]), np.array([ta, tb])
    qdd = forward_dynamics(q, qd, tau, FRICTIONAL)
    assert_allclose(inverse_dynamics(q, qd, qdd, FRICTIONAL), tau, atol=1e-10)
    floats = forward_dynamics_floats((a, b, ad, bd), (ta, tb), FRICTIONAL)
    assert_allclose(floats, qdd, rtol=1e-10, atol=1e-10)
    batch = forward_dynamics(np.tile(q, (3, 1)), np.tile(qd, (3, 1)), np.tile(tau, (3, 1)), FRICTIONAL)
    assert_allclose(batch, np.tile(qdd, (3, 1)), rtol=1e-12, atol=1e-12)


def test_friction_off_drops_every_friction_term() -> None:
    q, qd, tau = np.array([0.3, -0.2]), np.array([0.4, -0.6]), np.array([0.5, 1.0])
    without = dataclasses.replace(FRICTIONAL, viscous_friction=(0.0, 0.0), coulomb_friction=(0.0, 0.0))
    without = dataclasses.replace(without, torque_offset=(0.0, 0.0))
    assert_allclose(
        forward_dynamics(q, qd, tau, FRICTIONAL, friction=False),
        forward_dynamics(q, qd, tau, without),
        atol=0,
    )
    assert_allclose(
        forward_dynamics_floats((0.3, -0.2, 0.4, -0.6), (0.5, 1.0), FRICTIONAL, friction=False),
        forward_dynamics_floats((0.3, -0.2, 0.4, -0.6), (0.5, 1.0), without),
        atol=0,
    )


def test_offset_acts_as_a_constant_disturbance() -> None:
    """A torque offset enters like a constant external disturbance of the same value."""
    only_offset = SMMParameters(torque_offset=OFFSET)
    state, torque = (0.2, 0.1, 0.3, -0.4), (0.5, -0.3)
    assert_allclose(
        rk4_step_floats(state, torque, 1e-3, only_offset),
        rk4_step_floats(state, torque, 1e-3, SMMParameters(), disturbance=OFFSET),
        rtol=1e-15,
        atol=1e-15,
    )


@pytest.mark.parametrize(
    "params", [FRICTIONAL, SMMParameters(torque_offset=OFFSET), SMMParameters(coulomb_friction=COULOMB)]
)
def test_rk4_float_path_matches_array_path(params: SMMParameters) -> None:
    state = (0.2, -0.3, 0.8, -0.5)
    torque = (0.4, 1.2)
    q_next, qd_next = rk4_step(np.array(state[:2]), np.array(state[2:]), np.array(torque), 1e-3, params)
    assert_allclose(rk4_step_floats(state, torque, 1e-3, params), (*q_next, *qd_next), rtol=1e-12, atol=1e-12)


def test_coulomb_friction_brakes_a_free_joint_at_the_analytic_rate() -> None:
    """No gravity lever, alpha moving alone at beta = 0: M11 alpha'' = -f_c sign(alpha')."""
    params = SMMParameters(mass_lever=0.0, viscous_friction=(0.0, 0.0), coulomb_friction=(0.2, 0.0))
    qdd = forward_dynamics(np.zeros(2), np.array([0.5, 0.0]), np.zeros(2), params)
    m11 = mass_matrix(np.zeros(2), params)[0, 0]
    assert_allclose(qdd, (-0.2 / m11, 0.0), rtol=1e-14, atol=1e-15)
    qdd_back = forward_dynamics(np.zeros(2), np.array([-0.5, 0.0]), np.zeros(2), params)
    assert_allclose(qdd_back, (0.2 / m11, 0.0), rtol=1e-14, atol=1e-15)
