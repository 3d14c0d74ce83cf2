"""The regressor: Y theta is the inverse dynamics, for any parameters, in every term."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_analysis.identification.regressor import (
    PARAMETER_NAMES,
    parameter_vector,
    parameters_from_vector,
    regressor,
)

from smm_dynamics import SMMParameters, inverse_dynamics

positive = st.floats(0.01, 0.3)
friction = st.floats(0.0, 0.5)


@settings(max_examples=50, deadline=None)
@given(
    inertias=st.tuples(positive, positive, positive, positive),
    lever=st.floats(0.0, 0.1),
    viscous=st.tuples(friction, friction),
    coulomb=st.tuples(friction, friction),
    offset=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)),
    sign=st.sampled_from([1.0, -1.0]),
    seed=st.integers(0, 1000),
)
def test_y_theta_is_the_inverse_dynamics(
    *,
    inertias: tuple[float, float, float, float],
    lever: float,
    viscous: tuple[float, float],
    coulomb: tuple[float, float],
    offset: tuple[float, float],
    sign: float,
    seed: int,
) -> None:
    params = SMMParameters(
        I11=inertias[0],
        I22=inertias[1],
        I44=inertias[2],
        I55=inertias[3],
        mass_lever=lever,
        gravity_sign=sign,
        viscous_friction=viscous,
        coulomb_friction=coulomb,
        torque_offset=offset,
    )
    rng = np.random.default_rng(seed)
    q, qd, qdd = rng.uniform(-1.2, 1.2, (50, 2)), rng.uniform(-3, 3, (50, 2)), rng.uniform(-10, 10, (50, 2))
    qd[0] = 0.0  # sign(0) = 0 in both
    y = regressor(q, qd, qdd, gravity=params.gravity, gravity_sign=sign)
    assert y.shape == (50, 2, len(PARAMETER_NAMES))
    assert_allclose(
        y @ parameter_vector(params), inverse_dynamics(q, qd, qdd, params), atol=1e-12, rtol=1e-12
    )


def test_friction_and_offset_columns_are_per_joint() -> None:
    y = regressor(np.zeros((1, 2)), np.array([[0.5, -2.0]]), np.zeros((1, 2)), gravity=9.81, gravity_sign=1.0)
    names = list(PARAMETER_NAMES)
    assert y[0, 0, names.index("viscous_friction.alpha")] == 0.5
    assert y[0, 1, names.index("viscous_friction.alpha")] == 0.0
    assert y[0, 1, names.index("coulomb_friction.beta")] == -1.0
    assert y[0, 0, names.index("torque_offset.alpha")] == 1.0
    assert y[0, 1, names.index("torque_offset.alpha")] == 0.0


def test_vector_round_trip_keeps_gravity_and_geometry() -> None:
    base = SMMParameters(gravity=9.7, gravity_sign=-1.0, link_length=0.2)
    params = dataclasses.replace(base, I11=0.05, coulomb_friction=(0.1, 0.2), torque_offset=(-0.1, 0.0))
    rebuilt = parameters_from_vector(parameter_vector(params), base)
    assert rebuilt == params


def test_wrong_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="same shape"):
        regressor(np.zeros((3, 2)), np.zeros((2, 2)), np.zeros((3, 2)), gravity=9.81, gravity_sign=1.0)
    with pytest.raises(ValueError, match="theta must have shape"):
        parameters_from_vector(np.zeros(3), SMMParameters())
