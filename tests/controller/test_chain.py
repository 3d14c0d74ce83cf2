"""ControlChain runs TD -> FLESO -> controller (docs/DESIGN.md) and the factories use paper gains."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from smm_controller.baselines import FPDController, NPDController, PIDController
from smm_controller.chain import ControlChain, make_chain, make_controller
from smm_controller.fleso import FLESO
from smm_controller.fpdeso import FPDESOConfig, FPDESOController
from smm_controller.laws import UnknownLawError, get_law, law_names
from smm_controller.reference import SineReference
from smm_controller.td import TrackingDifferentiator

from smm_dynamics import SMMParameters

DT = 0.001
PARAMS = SMMParameters()


@pytest.mark.parametrize("velocity_source", ["td", "observer"])
def test_chain_equals_manual_composition_in_design_order(velocity_source: str) -> None:
    config = FPDESOConfig(velocity_source=velocity_source)
    chain = ControlChain(TrackingDifferentiator(), FLESO(None, PARAMS), FPDESOController(config, PARAMS))
    td, fleso, controller = TrackingDifferentiator(), FLESO(None, PARAMS), FPDESOController(config, PARAMS)
    references = SineReference().sample(np.arange(100) * DT)
    rng = np.random.default_rng(7)
    tau_applied = np.zeros(2)
    for k in range(100):
        y = references[k, 0] * 0.98 + rng.normal(0.0, 1e-3, 2)
        q, q_dot = td.step(y, DT)
        xi = fleso.step(q, tau_applied, DT)
        if velocity_source == "observer":
            q_dot = fleso.internals["x2_hat"]
        expected = controller.step(references[k], q, q_dot, xi, DT)
        got = chain.step(y, tau_applied, references[k], DT)
        assert_allclose(got, expected, rtol=0, atol=0)
        tau_applied = 0.9 * got
    internals = chain.internals
    assert_allclose(internals["fleso.xi_tilde"], fleso.internals["xi_tilde"], atol=0)
    assert_allclose(internals["disturbance_estimate"], fleso.internals["xi_tilde"], atol=0)
    assert_allclose(internals["td.x1"], td.internals["x1"], atol=0)
    assert_allclose(internals["controller.tau"], controller.internals["tau"], atol=0)


def test_without_observer_the_disturbance_estimate_is_zero() -> None:
    controller = FPDESOController(FPDESOConfig(robust_gain=(0.0, 0.0), velocity_source="td"), PARAMS)
    chain = ControlChain(TrackingDifferentiator(), None, controller)
    reference = SineReference().evaluate(0.1)
    chain.step([0.01, 0.02], [0.5, 0.5], reference, DT)
    assert_allclose(chain.internals["controller.disturbance"], [0.0, 0.0], atol=0)
    assert not any(key.startswith("fleso.") for key in chain.internals)


NO_OBSERVER = r"^the law's velocity_source is 'observer' but the chain has no FLESO$"


def test_the_observer_velocity_needs_an_observer() -> None:
    with pytest.raises(ValueError, match=NO_OBSERVER):
        ControlChain(TrackingDifferentiator(), None, FPDESOController(None, PARAMS))
    controller = FPDESOController(FPDESOConfig(velocity_source="td"), PARAMS)
    chain = ControlChain(TrackingDifferentiator(), None, controller)
    controller.reconfigure(FPDESOConfig(velocity_source="observer"))
    with pytest.raises(ValueError, match=NO_OBSERVER):
        chain.step([0.0, 0.0], [0.0, 0.0], SineReference().evaluate(0.0), DT)


def test_the_default_chain_gives_fpdeso_the_observer_velocity() -> None:
    chain = make_chain("fpdeso", PARAMS)
    assert chain.controller.velocity_source == "observer"
    assert chain.fleso is not None
    reference = SineReference().evaluate(0.0)
    for k in range(5):
        chain.step([0.001 * k, 0.0], [0.1, 0.1], reference, DT)
    # feedback = M u with u = kp e + kd (q_d' - x2^): recompute it from the observer's velocity.
    internals = chain.internals
    e_dot = reference[1] - internals["fleso.x2_hat"]
    e = reference[0] - internals["td.x1"]
    u = internals["controller.kp"] * e + internals["controller.kd"] * e_dot
    assert_allclose(internals["controller.u"], u, rtol=1e-12)


@pytest.mark.parametrize(
    ("name", "kind"),
    [("fpdeso", FPDESOController), ("fpd", FPDController), ("pid", PIDController), ("npd", NPDController)],
)
def test_make_controller(name: str, kind: type) -> None:
    assert isinstance(make_controller(name, PARAMS), kind)
    chain = make_chain(name, PARAMS)
    assert isinstance(chain.controller, kind)
    assert (chain.fleso is not None) == get_law(name).uses_disturbance_estimate == (name == "fpdeso")
    assert name in law_names()


def test_make_controller_rejects_unknown_names() -> None:
    with pytest.raises(UnknownLawError, match="unknown law 'lqr'; known: fpdeso, fpd, pid, npd"):
        make_controller("lqr", PARAMS)


def test_model_based_parts_reject_other_parameter_objects() -> None:
    with pytest.raises(ValueError, match="params must be SMMParameters"):
        FPDESOController(None, {"I11": 1.0})  # type: ignore[arg-type]


def test_step_validates_inputs() -> None:
    chain = make_chain("pid", PARAMS)
    with pytest.raises(ValueError, match="y must have shape"):
        chain.step([0.0, 0.0, 0.0], [0.0, 0.0], np.zeros((3, 2)), DT)
    with pytest.raises(ValueError, match="tau_applied must be finite"):
        chain.step([0.0, 0.0], [np.nan, 0.0], np.zeros((3, 2)), DT)
    with pytest.raises(ValueError, match="dt"):
        chain.step([0.0, 0.0], [0.0, 0.0], np.zeros((3, 2)), 0.0)


def test_the_chain_uses_the_limiter_it_is_given_and_tells_the_law_what_it_cut() -> None:
    from smm_controller.baselines import PIDConfig
    from smm_controller.limits import OutputLimitConfig, OutputLimiter

    # PI only (kd = 0): back-calculation with T_t = kp / ki = 2 s (control_toolbox's rule without kd).
    pid = PIDController(PIDConfig(kp=(4.0, 4.0), ki=(2.0, 2.0), kd=(0.0, 0.0)))
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(1.0, 1.0)))
    chain = ControlChain(TrackingDifferentiator(), None, pid, limiter=limiter)
    reference = [[1.0, -1.0], [0.0, 0.0], [0.0, 0.0]]  # 1 rad of error on each joint, at rest
    tau = chain.step_floats((0.0, 0.0), (0.0, 0.0), reference, DT)
    assert tau == (1.0, -1.0)  # cut at the given limiter's 1 N m, not the default 300 N m
    # The integral got ki e dt = +-0.002, then the anti-windup correction dt (limited - unlimited) / T_t;
    # a step with no error shows it (the integral does not move then).
    unlimited = 4.0 * 1.0 + 2.0 * 1.0 * DT
    expected = 2.0 * DT + DT * (1.0 - unlimited) / 2.0
    chain.step_floats((0.0, 0.0), (0.0, 0.0), [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], DT)
    assert_allclose(pid.internals["i"], [expected, -expected], rtol=1e-12)
