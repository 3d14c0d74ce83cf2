"""reconfigure(config): the new config acts from the next step, the dynamic state is kept (all algorithms).

The reference for "state kept" is a fresh algorithm built with the new config into which the old one's
dynamic state is copied. The dynamic state is found without naming private attributes: it is whatever
``reset()`` re-assigns or changes (config, model, fuzzy systems and sub-objects are left alone by reset).
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from controller.test_state import DT, PARAMS, run_controller, run_fleso, run_schedule, run_td
from numpy.testing import assert_allclose, assert_array_equal
from smm_controller.baselines import (
    FPDConfig,
    FPDController,
    NPDConfig,
    NPDController,
    PIDConfig,
    PIDController,
)
from smm_controller.fleso import FLESO, FLESOConfig
from smm_controller.fpdeso import FPDESOConfig, FPDESOController
from smm_controller.fuzzy_pd import PAPER_FPD_FUZZY, FuzzyPDConfig, FuzzyPDGainSchedule
from smm_controller.model import NominalModel
from smm_controller.td import TrackingDifferentiator, TrackingDifferentiatorConfig

HEAVIER = dataclasses.replace(PARAMS, I11=1.2 * PARAMS.I11, I55=1.1 * PARAMS.I55)
NEW_TD = TrackingDifferentiatorConfig(speed=(20.0, 60.0), filter_factor=(0.002, 0.003))  # nonlinear zone
NEW_FLESO = FLESOConfig(w0=(25.0, 30.0), k_w=(5.0, 12.0), k_s1=(4.0, 2.0), k_s2=(0.5, 1.5), grid_points=51)
NEW_FUZZY = FuzzyPDConfig(k_e=(3.0, 4.0), kp0=(3000.0, 5000.0), kd0=(90.0, 120.0), grid_points=101)
NEW_FPDESO = FPDESOConfig(fuzzy=NEW_FUZZY, robust_gain=(0.05, 0.2), boundary_layer=(0.5, 0.0))
NEW_PID = PIDConfig(
    kp=(20.0, 30.0),
    ki=(2.0, 1.0),
    kd=(0.5, 1.0),
    derivative_filter=(200.0, 800.0),
    integrator_limit=(5.0, 5.0),
)
NEW_NPD = NPDConfig(k_np=(40.0, 10.0), rho_p=(1.0, 0.8))
NEW_FPD = FPDConfig(fuzzy=dataclasses.replace(PAPER_FPD_FUZZY, kp0=(60.0, 30.0), grid_points=51))

Run = Callable[[Any, int], np.ndarray]


@dataclasses.dataclass(frozen=True)
class Case:
    """An algorithm with the old config, a fresh one with the new config, and the reconfigure call."""

    name: str
    make_old: Callable[[], Any]
    make_new: Callable[[], Any]
    reconfigure: Callable[[Any], None]
    run: Run
    stateful: bool


CASES = [
    Case("td", TrackingDifferentiator, lambda: TrackingDifferentiator(NEW_TD),
         lambda a: a.reconfigure(NEW_TD), run_td, stateful=True),
    Case("fleso", lambda: FLESO(None, PARAMS), lambda: FLESO(NEW_FLESO, PARAMS),
         lambda a: a.reconfigure(NEW_FLESO), run_fleso, stateful=True),
    Case("fleso-model", lambda: FLESO(None, PARAMS), lambda: FLESO(NEW_FLESO, HEAVIER),
         lambda a: a.reconfigure(NEW_FLESO, params=HEAVIER), run_fleso, stateful=True),
    Case("schedule", FuzzyPDGainSchedule, lambda: FuzzyPDGainSchedule(NEW_FUZZY),
         lambda a: a.reconfigure(NEW_FUZZY), run_schedule, stateful=False),
    Case("fpdeso", lambda: FPDESOController(None, PARAMS), lambda: FPDESOController(NEW_FPDESO, PARAMS),
         lambda a: a.reconfigure(NEW_FPDESO), run_controller, stateful=False),
    Case("fpdeso-model", lambda: FPDESOController(None, PARAMS),
         lambda: FPDESOController(NEW_FPDESO, HEAVIER),
         lambda a: a.reconfigure(NEW_FPDESO, params=HEAVIER), run_controller, stateful=False),
    Case("pid", PIDController, lambda: PIDController(NEW_PID),
         lambda a: a.reconfigure(NEW_PID), run_controller, stateful=True),
    Case("npd", NPDController, lambda: NPDController(NEW_NPD),
         lambda a: a.reconfigure(NEW_NPD), run_controller, stateful=False),
    Case("fpd", FPDController, lambda: FPDController(NEW_FPD),
         lambda a: a.reconfigure(NEW_FPD), run_controller, stateful=False),
]  # fmt: skip

_PLAIN = (list, tuple, dict, int, float, bool, type(None))


def dynamic_state(algorithm: Any) -> dict[str, Any]:
    """Deep copies of the attributes that ``reset()`` re-assigns or changes in place."""
    probe = copy.deepcopy(algorithm)
    before = dict(vars(probe))
    before_values = copy.deepcopy(before)
    probe.reset()
    return {
        name: before_values[name]
        for name, value in vars(probe).items()
        if value is not before[name] or (isinstance(value, _PLAIN) and value != before_values[name])
    }


def with_state(algorithm: Any, state: dict[str, Any]) -> Any:
    vars(algorithm).update(copy.deepcopy(state))
    return algorithm


def run_steps(algorithm: Any, run: Run, steps: range) -> np.ndarray:
    return np.array([run(algorithm, k) for k in steps])


WARM_UP = range(40)
AFTER = range(40, 60)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_next_outputs_equal_a_fresh_algorithm_with_the_same_state_and_the_new_config(case: Case) -> None:
    algorithm = case.make_old()
    run_steps(algorithm, case.run, WARM_UP)
    state = dynamic_state(algorithm)
    assert "config" not in state and state, sorted(state)
    case.reconfigure(algorithm)
    reference = with_state(case.make_new(), state)
    assert_array_equal(run_steps(algorithm, case.run, AFTER), run_steps(reference, case.run, AFTER))
    for key, value in algorithm.internals.items():
        assert_array_equal(value, reference.internals[key], err_msg=key)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_the_new_config_acts_and_the_state_matters_where_there_is_one(case: Case) -> None:
    algorithm = case.make_old()
    run_steps(algorithm, case.run, WARM_UP)
    unchanged = copy.deepcopy(algorithm)
    case.reconfigure(algorithm)
    after = run_steps(algorithm, case.run, AFTER)
    assert not np.allclose(after, run_steps(unchanged, case.run, AFTER))
    restarted = run_steps(case.make_new(), case.run, AFTER)
    if case.stateful:
        assert not np.allclose(after[0], restarted[0])
    else:
        assert_array_equal(after, restarted)


@pytest.mark.parametrize("case", [c for c in CASES if c.stateful], ids=[c.name for c in CASES if c.stateful])
def test_reconfigure_itself_does_not_touch_the_state(case: Case) -> None:
    algorithm = case.make_old()
    run_steps(algorithm, case.run, WARM_UP)
    internals = {key: value.copy() for key, value in algorithm.internals.items()}
    state = dynamic_state(algorithm)
    case.reconfigure(algorithm)
    assert dynamic_state(algorithm).keys() == state.keys()
    for key, value in algorithm.internals.items():
        assert_array_equal(value, internals[key], err_msg=key)


@pytest.mark.parametrize(
    ("make", "wrong", "expected"),
    [
        (TrackingDifferentiator, FLESOConfig(), "TrackingDifferentiatorConfig"),
        (lambda: FLESO(None, PARAMS), TrackingDifferentiatorConfig(), "FLESOConfig"),
        (FuzzyPDGainSchedule, FPDConfig(), "FuzzyPDConfig"),
        (lambda: FPDESOController(None, PARAMS), FuzzyPDConfig(), "FPDESOConfig"),
        (PIDController, NPDConfig(), "PIDConfig"),
        (NPDController, PIDConfig(), "NPDConfig"),
        (FPDController, PAPER_FPD_FUZZY, "FPDConfig"),
        (FPDController, None, "FPDConfig"),
    ],
)
def test_a_config_of_another_type_is_a_type_error_and_changes_nothing(
    make: Callable[[], Any], wrong: Any, expected: str
) -> None:
    algorithm = make()
    before = algorithm.config
    with pytest.raises(TypeError, match=rf"config must be a {expected}, got {type(wrong).__name__}"):
        algorithm.reconfigure(wrong)
    assert algorithm.config is before


@pytest.mark.parametrize(
    ("make", "config"),
    [(lambda: FLESO(None, PARAMS), NEW_FLESO), (lambda: FPDESOController(None, PARAMS), NEW_FPDESO)],
)
def test_model_parameters_of_another_type_are_a_type_error_and_change_nothing(
    make: Callable[[], Any], config: Any
) -> None:
    algorithm = make()
    config_before, model_before = algorithm.config, algorithm.model
    with pytest.raises(TypeError, match="params must be a SMMParameters, got dict"):
        algorithm.reconfigure(config, params=dataclasses.asdict(HEAVIER))
    assert algorithm.config is config_before and algorithm.model is model_before


# --------------------------------------------------------------------------------------------- FLESO


def test_fleso_keeps_a_converged_disturbance_estimate_across_a_gain_change() -> None:
    # At rest at q under tau = G(q) + d, the observer's steady state is xi~ = tau - G(q) = d (eq. 20).
    q = (0.3, 0.5)
    disturbance = np.array([0.4, -0.3])
    *_, g0, g1 = NominalModel.shared(PARAMS).bias(q[0], q[1], 0.0, 0.0)
    torque = np.array([g0, g1]) + disturbance
    fleso = FLESO(None, PARAMS)
    for _ in range(1500):
        estimate = fleso.step(q, torque, DT)
    assert_allclose(estimate, disturbance, rtol=0, atol=1e-9)
    fleso.reconfigure(dataclasses.replace(fleso.config, w0=(25.0, 30.0)))
    after = [fleso.step(q, torque, DT) for _ in range(200)]
    assert_allclose(after, np.tile(disturbance, (200, 1)), rtol=0, atol=1e-9)
    # What re-creating the observer did: the estimate dropped to 0, a bump of the whole disturbance.
    assert_array_equal(FLESO(fleso.config, PARAMS).step(q, torque, DT), [0.0, 0.0])


# ----------------------------------------------------------------------------------------------- PID


def constant_error_reference(error: float) -> np.ndarray:
    return np.array([[error, error], [0.0, 0.0], [0.0, 0.0]])


def integrate(pid: PIDController, error: float, steps: int) -> np.ndarray:
    tau = np.zeros(2)
    for _ in range(steps):
        tau = pid.step(constant_error_reference(error), [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], DT)
    return tau


INTEGRATOR_ONLY = PIDConfig(kp=(0.0, 0.0), ki=(1.0, 2.0), kd=(0.0, 0.0))


def test_pid_keeps_its_integrator_across_a_gain_change() -> None:
    pid = PIDController(INTEGRATOR_ONLY)
    integrate(pid, 0.5, 1000)
    integral = np.array([0.5, 1.0])  # ki * e * t
    assert_allclose(pid.internals["i"], integral, rtol=1e-12)
    pid.reconfigure(dataclasses.replace(INTEGRATOR_ONLY, kp=(2.0, 3.0)))
    tau = integrate(pid, 0.5, 1)
    expected_integral = integral + np.array([1.0, 2.0]) * 0.5 * DT
    assert_allclose(pid.internals["i"], expected_integral, rtol=1e-12)
    assert_allclose(tau, np.array([2.0, 3.0]) * 0.5 + expected_integral, rtol=1e-12)


def test_pid_integrator_is_re_clamped_to_a_new_limit_even_while_integration_is_held() -> None:
    pid = PIDController(INTEGRATOR_ONLY)
    integrate(pid, 0.5, 1000)
    # The output clamps at 0.1 and e pushes outwards, so the step holds I: only the re-clamp limits it.
    pid.reconfigure(
        dataclasses.replace(INTEGRATOR_ONLY, integrator_limit=(0.2, 0.3), output_limit=(0.1, 0.1))
    )
    tau = integrate(pid, 0.5, 1)
    assert_allclose(pid.internals["i"], [0.2, 0.3], rtol=0, atol=0)
    assert_allclose(tau, [0.1, 0.1], rtol=0, atol=0)


def test_pid_integrator_integrates_down_from_the_new_limit() -> None:
    pid = PIDController(INTEGRATOR_ONLY)
    integrate(pid, 0.5, 1000)
    pid.reconfigure(dataclasses.replace(INTEGRATOR_ONLY, integrator_limit=(0.2, 0.3)))
    tau = integrate(pid, -0.5, 1)
    expected = np.array([0.2, 0.3]) - np.array([1.0, 2.0]) * 0.5 * DT
    assert_allclose(tau, expected, rtol=1e-12)


def test_pid_unlimited_integrator_is_kept_as_is() -> None:
    pid = PIDController(INTEGRATOR_ONLY)
    integrate(pid, 0.5, 10)
    before = pid.internals["i"].copy()
    pid.reconfigure(dataclasses.replace(INTEGRATOR_ONLY, ki=(0.0, 0.0), integrator_limit=(math.inf, 1.0)))
    integrate(pid, 0.5, 1)
    assert_array_equal(pid.internals["i"], before)


# ------------------------------------------------------------------------------------ fuzzy systems


@pytest.mark.parametrize("grid_points", [51, 201])
def test_schedule_output_matches_a_fresh_schedule_after_a_grid_change(grid_points: int) -> None:
    schedule = FuzzyPDGainSchedule()
    new = dataclasses.replace(schedule.config, grid_points=grid_points)
    schedule.reconfigure(new)
    fresh = FuzzyPDGainSchedule(new)
    e, e_dot = np.array([0.11, -0.07]), np.array([0.05, 0.3])
    assert_array_equal(np.concatenate(schedule.step(e, e_dot)), np.concatenate(fresh.step(e, e_dot)))


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_the_algorithm_reports_its_new_config(case: Case) -> None:
    algorithm = case.make_old()
    case.reconfigure(algorithm)
    assert algorithm.config == case.make_new().config
