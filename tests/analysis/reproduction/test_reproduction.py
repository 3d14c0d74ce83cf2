"""Reproduction library: runs, acceptance checks, metrics document, ideal step response, TD sweep."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from smm_analysis.errors import AnalysisError, UnknownControllerError, UnknownScenarioError
from smm_analysis.metrics import step_metrics
from smm_analysis.reproduction import acceptance
from smm_analysis.reproduction.acceptance import acceptance_checks
from smm_analysis.reproduction.metrics_json import metrics_document
from smm_analysis.reproduction.reproduce import (
    ideal_step_response,
    resolve_controllers,
    resolve_scenarios,
    run_reproduction,
)
from smm_analysis.reproduction.results import JOINTS, ReproductionResult
from smm_analysis.reproduction.tune_td import TDSweepPoint, best_point, chosen_point, format_table, sweep_td
from smm_controller.laws import PAPER_LAWS

SHORT = 0.2


@pytest.fixture(scope="module")
def short_result() -> ReproductionResult:
    return run_reproduction(resolve_scenarios(["step", "case1", "case2"], SHORT), PAPER_LAWS)


@pytest.mark.parametrize(
    ("kp", "kd"), [(4050.0, 110.0), (4150.0, 90.0), (100.0, 5.0), (100.0, 25.0), (100.0, 30.0)]
)
def test_ideal_step_response_matches_sampled_analytic_response(kp: float, kd: float) -> None:
    overshoot, rise = ideal_step_response(kp, kd)
    omega, zeta = math.sqrt(kp), kd / (2.0 * math.sqrt(kp))
    if zeta < 1.0:
        assert_allclose(overshoot, math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta**2)), rtol=1e-12)
    else:
        assert overshoot == 0.0
    # Cross-check the rise time with the metrics on an exact simulation of e'' + kd e' + kp e = 0.
    t_ns = np.arange(0, 2_000_000_001, 20_000, dtype=np.int64)
    t = t_ns / 1e9
    matrix = np.array([[0.0, 1.0], [-kp, -kd]])
    eigenvalues, vectors = np.linalg.eig(matrix)
    coefficients = np.linalg.solve(vectors, np.array([1.0, 0.0]))
    error = np.real((vectors[0] * coefficients)[None, :] @ np.exp(np.outer(eigenvalues, t))).ravel()
    metrics = step_metrics(t_ns, 1.0 - error, 1.0)
    assert_allclose(rise, metrics.rise_time, rtol=1e-3)
    assert_allclose(overshoot, metrics.overshoot_fraction, atol=1e-6)
    assert omega > 0.0


def test_ideal_step_response_critically_damped() -> None:
    omega = 10.0
    overshoot, rise = ideal_step_response(omega**2, 2.0 * omega)
    t_ns = np.arange(0, 2_000_000_001, 20_000, dtype=np.int64)
    t = t_ns / 1e9
    metrics = step_metrics(t_ns, 1.0 - (1.0 + omega * t) * np.exp(-omega * t), 1.0)
    assert overshoot == 0.0
    assert_allclose(rise, metrics.rise_time, rtol=1e-3)


def test_ideal_step_response_rejects_bad_gains() -> None:
    with pytest.raises(AnalysisError):
        ideal_step_response(0.0, 1.0)


def test_every_scenario_and_controller_is_run(short_result: ReproductionResult) -> None:
    assert len(short_result.runs) == 12
    for (scenario, controller), run in short_result.runs.items():
        assert run.scenario == scenario and run.controller == controller
        assert (run.step is not None) == (scenario == "step")
        assert run.trajectory.t_ns[-1] == round(SHORT * 1e9)


def test_acceptance_checks_follow_the_metrics(short_result: ReproductionResult) -> None:
    checks = short_result.checks
    assert len(checks) == 12
    by_claim: dict[tuple[str, str], float] = {(check.claim, check.joint): check.value for check in checks}
    step = short_result.run("step", "fpdeso")
    assert step is not None and step.step is not None
    for joint in JOINTS:
        overshoot = by_claim[("step: FPDESO overshoot (fraction of the step)", joint)]
        assert overshoot == step.step[joint].overshoot_fraction
    fpdeso, fpd = short_result.run("case2", "fpdeso"), short_result.run("case2", "fpd")
    assert fpdeso is not None and fpd is not None
    for check in checks:
        if check.quantity == "rms_reduction":
            expected = 1.0 - fpdeso.joints[check.joint].RMS / fpd.joints[check.joint].RMS
            assert check.value == pytest.approx(expected)
            assert check.passed == (expected >= 0.38)
        if check.quantity == "eps_u":
            energy, fpd_energy = fpdeso.joints[check.joint].eps_u, fpd.joints[check.joint].eps_u
            assert check.scenario == "case2" and check.value == energy
            assert check.passed == (energy < fpd_energy)
        if check.claim.startswith("case1: FPDESO has the lowest RMS"):
            others = [
                run.joints[check.joint].RMS
                for (scenario, name), run in short_result.runs.items()
                if scenario == "case1" and name != "fpdeso"
            ]
            assert check.passed == (check.value < min(others))


def test_acceptance_thresholds_are_applied(
    short_result: ReproductionResult, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(acceptance, "STEP_OVERSHOOT_LIMIT", 0.0)
    strict = [check for check in acceptance_checks(short_result) if "overshoot" in check.claim]
    assert strict and not any(check.passed for check in strict)
    monkeypatch.setattr(acceptance, "STEP_OVERSHOOT_LIMIT", 1.0)
    loose = [check for check in acceptance_checks(short_result) if "overshoot" in check.claim]
    assert all(check.passed for check in loose)


def test_checks_without_their_runs_are_left_out() -> None:
    result = run_reproduction(resolve_scenarios(["case2"], 0.05), ("fpdeso",))
    assert result.checks == ()


def test_metrics_document_schema(short_result: ReproductionResult) -> None:
    document = metrics_document(short_result)
    text = json.dumps(document, allow_nan=False)
    assert json.loads(text) == document
    assert set(document) == {"step", "case1", "case2", "acceptance", "acceptance_verdict", "meta"}
    for scenario in ("step", "case1", "case2"):
        per_scenario = document[scenario]
        assert isinstance(per_scenario, dict)
        assert set(per_scenario) == set(PAPER_LAWS)
        for entry in per_scenario.values():
            for joint in JOINTS:
                values = entry[joint]
                assert {"Ma", "Ave", "RMS", "eps_u", "du_rms"} <= set(values)
                step_keys = {"rise_time", "overshoot", "overshoot_fraction", "settling_time"}
                assert (step_keys <= set(values)) == (scenario == "step")
            assert set(entry["end_effector"]) == {"x", "y", "z"}
    run = short_result.run("case1", "fpdeso")
    assert run is not None
    case1 = document["case1"]
    assert isinstance(case1, dict)
    assert case1["fpdeso"]["beta"]["RMS"] == run.joints["beta"].RMS
    assert case1["fpdeso"]["beta"]["du_rms"] == run.joints["beta"].du_rms
    acceptance = document["acceptance"]
    assert isinstance(acceptance, list) and len(acceptance) == 12
    assert all(isinstance(item["passed"], bool) for item in acceptance)


def test_unsettled_step_is_null_in_json() -> None:
    result = run_reproduction(resolve_scenarios(["step"], 0.02), ("pid",))
    document = metrics_document(result)
    step = document["step"]
    assert isinstance(step, dict)
    assert step["pid"]["alpha"]["settling_time"] is None
    json.dumps(document, allow_nan=False)


def test_resolution_errors() -> None:
    with pytest.raises(UnknownScenarioError):
        resolve_scenarios(["step", "nope"])
    with pytest.raises(AnalysisError, match="duplicate"):
        resolve_scenarios(["step", "step"])
    with pytest.raises(AnalysisError, match="duration"):
        resolve_scenarios(["step"], -1.0)
    with pytest.raises(UnknownControllerError):
        resolve_controllers(["pid", "lqr"])
    with pytest.raises(AnalysisError, match="at least one"):
        resolve_controllers([])


def test_td_sweep_scores_each_pair_and_picks_the_lowest() -> None:
    scenario = resolve_scenarios(["case2"], 0.3)[0]
    points = sweep_td((1.0e5,), (0.001, 0.004), scenario=scenario)
    assert [(point.speed, point.filter_factor) for point in points] == [(1.0e5, 0.001), (1.0e5, 0.004)]
    best = best_point(points)
    assert best.rms_sum == min(point.rms_sum for point in points)
    table = format_table(points)
    assert table.count("**") == 2
    assert "| 1 | 4 |" in table.splitlines()[0].replace(" ", " ")
    with pytest.raises(AnalysisError, match="below the control period"):
        sweep_td((1.0e5,), (0.0005,), scenario=scenario)


def test_chosen_td_point_is_the_middle_of_the_sigma_plateau_at_the_best_h() -> None:
    points = [
        TDSweepPoint(1.0e3, 0.001, 0.0045, 0.0031),
        TDSweepPoint(1.0e4, 0.001, 0.0029141, 0.0022670),
        TDSweepPoint(1.0e5, 0.001, 0.0029140, 0.0022670),
        TDSweepPoint(1.0e6, 0.001, 0.0029139, 0.0022670),
        TDSweepPoint(1.0e5, 0.002, 0.0047, 0.0036),
        TDSweepPoint(1.0e5, 0.008, math.inf, math.inf),
    ]
    assert best_point(points).speed == 1.0e6
    chosen = chosen_point(points)
    assert (chosen.speed, chosen.filter_factor) == (1.0e5, 0.001)
    assert chosen_point(points, tolerance=0.0).speed == 1.0e6
    assert "inf / inf" in format_table(points)
