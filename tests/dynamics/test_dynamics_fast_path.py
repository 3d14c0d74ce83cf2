"""The plain-float fast path (spin form) equals the reference array functions up to rounding."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

import smm_dynamics
from smm_dynamics import (
    SMMParameters,
    forward_dynamics,
    forward_dynamics_floats,
    gravity_vector,
    mass_matrix,
    mass_matrix_floats,
    mass_matrix_inverse,
    rigid_body_floats,
    rigid_body_terms,
    rk4_step,
    rk4_step_floats,
)

RTOL = 1e-12
# Rates of order 1e-157 make C q' subnormal, where a relative tolerance means nothing.
TINY = 1e-290
DISTINCT = SMMParameters(I11=0.05, I22=0.08, I44=0.11, I55=0.07, viscous_friction=(0.3, 0.2))
HANGING = SMMParameters(gravity_sign=-1.0, mass_lever=0.05)
PARAMETER_SETS = (SMMParameters(), DISTINCT, HANGING, SMMParameters().with_inertia_scale(1.1))

angles = st.floats(-1.3, 1.3, allow_nan=False, allow_subnormal=True)
rates = st.floats(-8.0, 8.0, allow_nan=False, allow_subnormal=True)
torques = st.floats(-5.0, 5.0, allow_nan=False, allow_subnormal=True)
parameter_sets = st.sampled_from(PARAMETER_SETS)


def _coriolis_scale(beta: float, alpha_dot: float, beta_dot: float, params: SMMParameters) -> float:
    """Bound on the terms summed into C q' (N m): rounding is relative to it, not to C q' itself.

    The entries of C are inertias times rates over d^2 and d = sin^2(a) + cos^2(a) cos^2(b) >= cos^2(b).
    """
    return (params.I11 + params.I55) * (abs(alpha_dot) + abs(beta_dot)) ** 2 / math.cos(beta) ** 4


@settings(max_examples=200, deadline=None)
@given(a=angles, b=angles, params=parameter_sets)
def test_mass_matrix_floats_matches_mass_matrix(a: float, b: float, params: SMMParameters) -> None:
    mass = mass_matrix(np.array([a, b]), params)
    reference = (mass[0, 0], mass[0, 1], mass[1, 1])
    # M12 vanishes on alpha = 0 or beta = 0: there rounding is relative to the diagonal.
    assert_allclose(mass_matrix_floats(a, b, params), reference, rtol=RTOL, atol=RTOL * mass[0, 0])


@settings(max_examples=200, deadline=None)
@given(a=angles, b=angles, ad=rates, bd=rates, params=parameter_sets)
def test_rigid_body_floats_matches_rigid_body_terms(
    a: float, b: float, ad: float, bd: float, params: SMMParameters
) -> None:
    fast = rigid_body_floats(a, b, ad, bd, params)
    reference = rigid_body_terms(a, b, ad, bd, params)
    mass_scale = reference[0]
    coriolis_scale = _coriolis_scale(b, ad, bd, params)
    assert_allclose(fast[:3], reference[:3], rtol=RTOL, atol=RTOL * mass_scale)
    assert_allclose(fast[3:5], reference[3:5], rtol=RTOL, atol=RTOL * coriolis_scale + TINY)
    assert fast[5:] == reference[5:]  # gravity: the same expression
    assert fast[:3] == mass_matrix_floats(a, b, params)  # one M for mass() and bias() of a model


@settings(max_examples=200, deadline=None)
@given(
    a=angles,
    b=angles,
    ad=rates,
    bd=rates,
    tau=st.tuples(torques, torques),
    dist=st.tuples(torques, torques),
    friction=st.booleans(),
    params=parameter_sets,
)
def test_forward_dynamics_floats_matches_forward_dynamics(
    *,
    a: float,
    b: float,
    ad: float,
    bd: float,
    tau: tuple[float, float],
    dist: tuple[float, float],
    friction: bool,
    params: SMMParameters,
) -> None:
    q, qd = np.array([a, b]), np.array([ad, bd])
    fast = forward_dynamics_floats((a, b, ad, bd), tau, params, disturbance=dist, friction=friction)
    reference = forward_dynamics(q, qd, np.array(tau), params, tau_dist=np.array(dist), friction=friction)
    # Rounding is relative to the torques that are summed before M^-1 is applied.
    summed = (
        np.abs(tau)
        + np.abs(dist)
        + np.abs(gravity_vector(q, params))
        + np.abs(np.asarray(params.viscous_friction) * qd)
        + _coriolis_scale(b, ad, bd, params)
    )
    scale = float(np.max(np.abs(mass_matrix_inverse(q, params)) @ summed))
    assert_allclose(fast, reference, rtol=RTOL, atol=RTOL * scale + TINY)


@settings(max_examples=150, deadline=None)
@given(
    a=angles,
    b=angles,
    ad=rates,
    bd=rates,
    tau=st.tuples(torques, torques),
    dist=st.tuples(torques, torques),
    friction=st.booleans(),
    dt=st.sampled_from((1e-4, 1e-3, 5e-3)),
    params=parameter_sets,
)
def test_rk4_step_floats_matches_rk4_step(
    *,
    a: float,
    b: float,
    ad: float,
    bd: float,
    tau: tuple[float, float],
    dist: tuple[float, float],
    friction: bool,
    dt: float,
    params: SMMParameters,
) -> None:
    fast = rk4_step_floats((a, b, ad, bd), tau, dt, params, disturbance=dist, friction=friction)
    q, qd = rk4_step(
        np.array([a, b]),
        np.array([ad, bd]),
        np.array(tau),
        dt,
        params,
        tau_dist=np.array(dist),
        friction=friction,
    )
    # A state component may pass through zero: rounding is relative to the state's size.
    assert_allclose(fast[:2], q, rtol=RTOL, atol=RTOL * (1.0 + abs(a) + abs(b)))
    assert_allclose(fast[2:], qd, rtol=RTOL, atol=RTOL * (1.0 + abs(ad) + abs(bd)))


def test_rk4_step_floats_defaults_are_no_disturbance_and_friction_on() -> None:
    state, torque = (0.4, -0.3, 1.2, -0.7), (0.5, -0.2)
    assert rk4_step_floats(state, torque, 1e-3, DISTINCT) == rk4_step_floats(
        state, torque, 1e-3, DISTINCT, disturbance=(0.0, 0.0), friction=True
    )
    assert rk4_step_floats(state, torque, 1e-3, DISTINCT) != rk4_step_floats(
        state, torque, 1e-3, DISTINCT, friction=False
    )


def test_rk4_step_floats_of_a_long_run_stays_with_the_reference() -> None:
    """2 s at 1 ms with a varying torque: the two integrations stay together to rounding."""
    state = (0.2, -0.1, 0.0, 0.0)
    q, qd = np.array(state[:2]), np.array(state[2:])
    for k in range(2000):
        torque = (0.3 * math.sin(0.01 * k), 0.4 * math.cos(0.007 * k))
        state = rk4_step_floats(state, torque, 1e-3, DISTINCT)
        q, qd = rk4_step(q, qd, np.array(torque), 1e-3, DISTINCT)
    assert_allclose(state[:2], q, rtol=1e-11, atol=1e-13)
    assert_allclose(state[2:], qd, rtol=1e-11, atol=1e-13)


@pytest.mark.parametrize("dt", [0.0, -1e-3, math.inf, math.nan])
def test_rk4_step_floats_rejects_bad_steps(dt: float) -> None:
    with pytest.raises(ValueError, match="dt"):
        rk4_step_floats((0.0, 0.0, 0.0, 0.0), (0.0, 0.0), dt, DISTINCT)


def _load_generator() -> ModuleType:
    path = Path(smm_dynamics.__file__).resolve().parent.parent / "tools" / "generate_dynamics.py"
    spec = importlib.util.spec_from_file_location("generate_dynamics_under_test", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_generator_rejects_a_wrong_spin_form() -> None:
    """The proof that runs on every generation (test_dynamics_generated) is able to fail."""
    sp = pytest.importorskip("sympy")
    generator = _load_generator()
    constants, mass_stages, coriolis_stages = generator.spin_form_stages()
    wrong_mass = [
        (symbol, expr + generator.I55 * sp.Rational(1, 100) if symbol == generator.M22 else expr)
        for symbol, expr in mass_stages
    ]
    with pytest.raises(AssertionError, match="m22"):
        generator.check_spin_form([*constants, *wrong_mass, *coriolis_stages])
    wrong_coriolis = [
        (symbol, expr * 2 if symbol == generator.CORIOLIS_BETA else expr) for symbol, expr in coriolis_stages
    ]
    with pytest.raises(AssertionError, match="coriolis_beta"):
        generator.check_spin_form([*constants, *mass_stages, *wrong_coriolis])
