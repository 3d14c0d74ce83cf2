"""FPDESO law (eq. 26-30) and the controller's float model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_controller.fpdeso import FPDESOConfig, FPDESOController, robust_switch
from smm_controller.model import NominalModel

from smm_dynamics import (
    SMMParameters,
    coriolis_vector,
    forward_dynamics,
    gravity_vector,
    mass_matrix,
    mass_matrix_inverse,
)

DT = 0.001
PARAMS = SMMParameters()
TINY = float(np.finfo(np.float64).tiny)  # smallest normal float64; below it only subnormal rounding remains
angles = st.floats(-1.2, 1.2, allow_subnormal=True)
rates = st.floats(-3.0, 3.0, allow_subnormal=True)
small = st.floats(-0.3, 0.3, allow_subnormal=True)


def reference(
    q: np.ndarray, e: np.ndarray, e_dot: np.ndarray, qd: np.ndarray, qdd_d: np.ndarray
) -> np.ndarray:
    return np.array([q + e, qd + e_dot, qdd_d])


@settings(deadline=None, max_examples=60)
@given(
    state=st.tuples(angles, angles, rates, rates),
    errors=st.tuples(small, small, small, small),
    acc=st.floats(-10, 10, allow_subnormal=True),
)
def test_decoupling_on_the_exact_model(
    state: tuple[float, float, float, float], errors: tuple[float, float, float, float], acc: float
) -> None:
    """xi~ = 0, b_d = 0, friction off: the plant's acceleration is q_d'' + u (eq. 10), joint by joint."""
    a, b, ad, bd = state
    ea, eb, eda, edb = errors
    controller = FPDESOController(FPDESOConfig(robust_gain=(0.0, 0.0)), PARAMS)
    q, qd = np.array([a, b]), np.array([ad, bd])
    qdd_d = np.array([acc, -0.5 * acc])
    tau = controller.step(
        reference(q, np.array([ea, eb]), np.array([eda, edb]), qd, qdd_d), q, qd, np.zeros(2), DT
    )
    u = controller.internals["u"]
    assert_allclose(forward_dynamics(q, qd, tau, PARAMS, friction=False), qdd_d + u, rtol=1e-9, atol=1e-7)


def test_u_is_the_scheduled_pd_law() -> None:
    controller = FPDESOController(None, PARAMS)
    q, qd = np.array([0.3, -0.2]), np.array([0.5, 0.1])
    e, e_dot = np.array([0.02, -0.01]), np.array([0.1, 0.05])
    controller.step(reference(q, e, e_dot, qd, np.zeros(2)), q, qd, np.zeros(2), DT)
    internals = controller.internals
    assert_allclose(internals["u"], internals["kp"] * e + internals["kd"] * e_dot, rtol=1e-12)


def test_terms_add_up_and_match_the_model() -> None:
    controller = FPDESOController(None, PARAMS)
    q, qd = np.array([0.4, 0.3]), np.array([-0.6, 0.8])
    qdd_d = np.array([2.0, -1.0])
    xi = np.array([0.07, -0.03])
    tau = controller.step(
        reference(q, np.array([0.01, 0.02]), np.array([0.3, -0.2]), qd, qdd_d), q, qd, xi, DT
    )
    internals = controller.internals
    m = mass_matrix(q, PARAMS)
    assert_allclose(
        internals["feedforward"],
        m @ qdd_d + coriolis_vector(q, qd, PARAMS) + gravity_vector(q, PARAMS),
        rtol=1e-12,
    )
    assert_allclose(internals["feedback"], m @ internals["u"], rtol=1e-12)
    assert_allclose(internals["disturbance"], xi, atol=0)
    assert_allclose(
        tau,
        internals["feedforward"] + internals["feedback"] + internals["disturbance"] - internals["robust"],
        rtol=1e-13,
    )


@pytest.mark.parametrize("e_dot", [(0.3, -0.2), (-0.05, 0.4), (1.0, 1.0)])
def test_robust_term_is_minus_bd_sign_of_minv_edot(e_dot: tuple[float, float]) -> None:
    b_d = (0.2, 0.1)
    with_robust = FPDESOController(FPDESOConfig(robust_gain=b_d), PARAMS)
    without = FPDESOController(FPDESOConfig(robust_gain=(0.0, 0.0)), PARAMS)
    q, qd = np.array([0.5, 0.7]), np.zeros(2)
    ref = reference(q, np.zeros(2), np.array(e_dot), qd, np.zeros(2))
    tau_r = with_robust.step(ref, q, qd, np.zeros(2), DT)
    tau_0 = without.step(ref, q, qd, np.zeros(2), DT)
    v = -np.array(b_d) * np.sign(mass_matrix_inverse(q, PARAMS) @ np.array(e_dot))
    assert_allclose(with_robust.internals["robust"], v, atol=0)
    assert_allclose(tau_r - tau_0, -v, rtol=1e-12)


def test_robust_term_sign_follows_minv_not_edot() -> None:
    """With strong coupling M^-1 e' has the opposite sign of e' in one joint; v follows M^-1 e'."""
    q, e_dot = np.array([0.6, 1.1]), np.array([1.0, 3.0])
    z = mass_matrix_inverse(q, PARAMS) @ e_dot
    assert np.sign(z[0]) != np.sign(e_dot[0])
    controller = FPDESOController(FPDESOConfig(robust_gain=(1.0, 1.0)), PARAMS)
    controller.step(
        reference(q, np.zeros(2), e_dot, np.zeros(2), np.zeros(2)), q, np.zeros(2), np.zeros(2), DT
    )
    assert_allclose(controller.internals["robust"], -np.sign(z))


@pytest.mark.parametrize(
    ("x", "phi", "expected"),
    [
        (0.5, 0.0, 1.0),
        (-0.5, 0.0, -1.0),
        (0.0, 0.0, 0.0),
        (0.5, 1.0, 0.5),
        (-3.0, 1.0, -1.0),
        (2.0, 1.0, 1.0),
    ],
)
def test_robust_switch(x: float, phi: float, expected: float) -> None:
    assert robust_switch(x, phi) == expected


def test_boundary_layer_scales_the_robust_term() -> None:
    q, qd = np.array([0.2, 0.1]), np.zeros(2)
    e_dot = np.array([1e-3, -2e-3])
    phi = (1.0, 1.0)
    controller = FPDESOController(FPDESOConfig(robust_gain=(0.1, 0.1), boundary_layer=phi), PARAMS)
    controller.step(reference(q, np.zeros(2), e_dot, qd, np.zeros(2)), q, qd, np.zeros(2), DT)
    z = mass_matrix_inverse(q, PARAMS) @ e_dot
    assert np.all(np.abs(z) < 1.0)
    assert_allclose(controller.internals["robust"], -0.1 * z, rtol=1e-12)


class TestNominalModel:
    @settings(deadline=None, max_examples=60)
    @given(a=angles, b=angles, ad=rates, bd=rates)
    @example(a=2.2250738585e-313, b=0.8433, ad=0.0, bd=0.0)  # subnormal alpha: M12 ~ 3e-314, 1 ulp apart
    def test_matches_smm_dynamics(self, a: float, b: float, ad: float, bd: float) -> None:
        """Agrees with smm_dynamics to rounding, relative to each term's scale (entries may be subnormal)."""
        params = SMMParameters(gravity_sign=-1.0, mass_lever=0.05)
        model = NominalModel(params)
        q, qd = np.array([a, b]), np.array([ad, bd])
        m11, m12, m22, c0, c1, g0, g1 = model.bias(a, b, ad, bd)
        mass = mass_matrix(q, params)
        coriolis, gravity = coriolis_vector(q, qd, params), gravity_vector(q, params)
        # Absolute tolerance: rounding relative to each term's scale; TINY covers products that underflow.
        mass_scale = np.abs(mass).max()
        assert_allclose([[m11, m12], [m12, m22]], mass, rtol=1e-13, atol=1e-15 * mass_scale)
        coriolis_scale = mass_scale * (ad * ad + bd * bd)  # |C q'| <= ~|dM/dq| |q'|^2, |dM/dq| ~ |M|
        assert_allclose([c0, c1], coriolis, rtol=1e-12, atol=1e-14 * coriolis_scale + TINY)
        gravity_scale = params.mass_lever * params.gravity
        assert_allclose([g0, g1], gravity, rtol=1e-13, atol=1e-15 * gravity_scale + TINY)
        assert_allclose(model.mass(a, b), (m11, m12, m22), rtol=0)

    def test_memo_is_keyed_on_the_position(self) -> None:
        model = NominalModel(PARAMS)
        first = model.mass(0.1, 0.2)
        model.mass(0.3, -0.4)
        assert model.mass(0.1, 0.2) == first
        assert model.mass(0.3, -0.4) != first

    def test_shared_per_parameter_set(self) -> None:
        assert NominalModel.shared(PARAMS) is NominalModel.shared(SMMParameters())
        assert NominalModel.shared(PARAMS) is not NominalModel.shared(SMMParameters(I55=0.08))

    def test_rejects_other_parameter_objects(self) -> None:
        with pytest.raises(ValueError, match="SMMParameters"):
            NominalModel(math.pi)  # type: ignore[arg-type]


def test_velocity_source_is_validated_and_defaults_to_the_observer() -> None:
    assert FPDESOConfig().velocity_source == "observer"
    assert FPDESOController(FPDESOConfig(velocity_source="td"), PARAMS).velocity_source == "td"
    with pytest.raises(ValueError, match="velocity_source must be one of"):
        FPDESOConfig(velocity_source="encoder")
