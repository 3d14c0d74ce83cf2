"""Offline closed loop: order of DESIGN.md, determinism, chain composition, errors, case2 claim."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from smm_analysis.closed_loop import run_closed_loop, scenario_plant_config
from smm_analysis.errors import (
    AnalysisError,
    ClosedLoopDivergedError,
    UnknownControllerError,
    UnknownScenarioError,
)
from smm_analysis.metrics import rms_error
from smm_analysis.scenarios import SCENARIOS
from smm_controller.laws import PAPER_LAWS
from smm_sim.plant import SimulatedPlant

from smm_controller import ControlChain, FPDController, TrackingDifferentiator, make_chain
from smm_dynamics import SMMParameters

SHORT_CASE2 = SCENARIOS["case2"].with_duration(1.2)  # crosses the eq. 46 onset at 1 s


def test_trajectory_shapes_and_time_base() -> None:
    run = run_closed_loop(SCENARIOS["case1"].with_duration(0.05), "fpd")
    assert run.t_ns.dtype == np.int64
    assert_array_equal(run.t_ns, np.arange(51, dtype=np.int64) * 1_000_000)
    assert run.reference.shape == (51, 3, 2)
    for array in (run.measured_position, run.position, run.velocity, run.command_torque, run.applied_torque):
        assert array.shape == (51, 2)
    assert_allclose(run.desired_position[:, 0], np.sin(np.pi * run.time), atol=1e-15)
    assert_allclose(run.desired_position[:, 1], 0.785 * np.sin(np.pi * run.time), atol=1e-15)


def test_loop_follows_the_design_order() -> None:
    """A hand-written loop in the documented order gives the same commands, bit for bit."""
    scenario = SHORT_CASE2
    run = run_closed_loop(scenario, "fpdeso", seed=5)
    plant = SimulatedPlant(scenario_plant_config(scenario, seed=5))
    chain = make_chain("fpdeso", SMMParameters())
    reference = scenario.reference()
    commands = []
    for k in range(run.t_ns.size):
        sample = plant.measure()  # y_k and the torque applied over [t_{k-1}, t_k]
        tau = chain.step(sample.position, sample.applied_torque, reference.evaluate(run.t_ns[k] / 1e9), 1e-3)
        commands.append(tau)
        plant.step(tau, 1e-3)
    assert_array_equal(np.array(commands), run.command_torque)


def test_same_seed_is_deterministic_and_seeds_differ() -> None:
    first = run_closed_loop(SHORT_CASE2, "fpdeso", seed=1)
    second = run_closed_loop(SHORT_CASE2, "fpdeso", seed=1)
    for name in ("measured_position", "position", "velocity", "command_torque", "disturbance_estimate"):
        assert_array_equal(getattr(first, name), getattr(second, name))
    for key, value in first.internals.items():
        assert_array_equal(value, second.internals[key])
    other = run_closed_loop(SHORT_CASE2, "fpdeso", seed=2)
    assert not np.array_equal(first.measured_position, other.measured_position)
    assert not np.array_equal(first.position, other.position)


def test_fpdeso_gets_fleso_and_baselines_do_not() -> None:
    scenario = SCENARIOS["case1"].with_duration(0.1)
    fpdeso = run_closed_loop(scenario, "fpdeso")
    assert any(key.startswith("fleso.") for key in fpdeso.internals)
    assert np.any(fpdeso.disturbance_estimate != 0.0)
    assert_array_equal(fpdeso.disturbance_estimate, fpdeso.internals["fleso.xi_tilde"])
    for name in PAPER_LAWS[1:]:
        baseline = run_closed_loop(scenario, name)
        assert not any(key.startswith("fleso.") for key in baseline.internals)
        assert any(key.startswith("td.") for key in baseline.internals)
        assert_array_equal(baseline.disturbance_estimate, 0.0)


def test_effort_fed_back_is_the_applied_torque() -> None:
    run = run_closed_loop(SCENARIOS["case1"].with_duration(0.05), "pid")
    # No saturation or lag in the scenarios: the plant applies exactly the command.
    assert_array_equal(run.applied_torque, run.command_torque)


def test_noise_reaches_the_chain_but_not_the_error() -> None:
    run = run_closed_loop(SHORT_CASE2, "fpd")
    noise = run.measured_position - run.position
    assert 0.0007 < float(np.std(noise)) < 0.0013
    assert_array_equal(run.tracking_error, run.desired_position - run.position)


def test_model_error_and_disturbance_reach_the_plant() -> None:
    run = run_closed_loop(SHORT_CASE2, "fpd")
    assert pytest.approx(1.1 * run.model_params.I55) == run.plant_params.I55
    after_onset = run.time > 1.0
    assert_array_equal(run.disturbance_torque[~after_onset], 0.0)
    assert_allclose(run.disturbance_torque[after_onset, 1], 0.5 * np.cos(7.0 * run.time[after_onset]))


def test_substeps_do_not_change_the_result() -> None:
    coarse = run_closed_loop(SHORT_CASE2, "fpdeso", record_internals=False)
    fine = run_closed_loop(SHORT_CASE2, "fpdeso", substeps=8, record_internals=False)
    for joint in range(2):
        assert_allclose(
            rms_error(fine.t_ns, fine.tracking_error[:, joint]),
            rms_error(coarse.t_ns, coarse.tracking_error[:, joint]),
            rtol=1e-5,
        )


def test_unknown_names_and_bad_duration_are_rejected() -> None:
    with pytest.raises(UnknownScenarioError, match="case9"):
        run_closed_loop("case9", "fpdeso")
    with pytest.raises(UnknownControllerError, match="lqr"):
        run_closed_loop("step", "lqr")
    with pytest.raises(AnalysisError, match="whole number"):
        run_closed_loop(SCENARIOS["step"].with_duration(0.0105), "pid")
    with pytest.raises(AnalysisError, match="control_period"):
        run_closed_loop("step", "pid", control_period=0.0)


class _ExplodingController(FPDController):
    """FPD until step 20, then NaN (stands in for an unstable loop)."""

    def __init__(self) -> None:
        super().__init__()
        self.calls = 0

    def step_floats(self, *args: Any, **kwargs: Any) -> tuple[float, float]:
        self.calls += 1
        if self.calls > 20:
            return float("nan"), 0.0
        result: tuple[float, float] = super().step_floats(*args, **kwargs)
        return result

    def step(self, *args: Any, **kwargs: Any) -> Any:
        self.calls += 1
        if self.calls > 20:
            return np.array([float("nan"), 0.0])
        return super().step(*args, **kwargs)


def test_non_finite_torque_stops_the_run_with_a_typed_error() -> None:
    with pytest.raises(ClosedLoopDivergedError, match="step 20"):
        run_closed_loop(SCENARIOS["step"].with_duration(0.1), "fpd", controller=_ExplodingController())


def test_custom_controller_replaces_the_default_gains() -> None:
    scenario = SCENARIOS["step"].with_duration(0.05)
    default = run_closed_loop(scenario, "fpd")
    same = run_closed_loop(scenario, "fpd", controller=FPDController())
    assert_array_equal(default.command_torque, same.command_torque)


def _rms(run: Any) -> Sequence[float]:
    return [rms_error(run.t_ns, run.tracking_error[:, joint]) for joint in range(2)]


@pytest.mark.slow
def test_case2_fpdeso_rms_at_least_38_percent_below_fpd() -> None:
    """The paper's case 2 claim (Table 4: 56 % / 38 % lower RMS), on the full 5 s scenario."""
    fpdeso = _rms(run_closed_loop("case2", "fpdeso", record_internals=False))
    fpd = _rms(run_closed_loop("case2", "fpd", record_internals=False))
    for ours, theirs in zip(fpdeso, fpd, strict=True):
        assert ours <= (1.0 - 0.38) * theirs


def test_chain_built_for_the_loop_matches_the_factory() -> None:
    chain: ControlChain = make_chain("fpd", SMMParameters())
    assert chain.fleso is None
    assert isinstance(chain.td, TrackingDifferentiator)
    internals: Mapping[str, Any] = run_closed_loop(SCENARIOS["step"].with_duration(0.01), "fpd").internals
    assert set(internals) == set(chain.internals)
