"""The clearly labelled retuned FPDESO set: its data, its rule, its runs and the acceptance verdict."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest
from numpy.testing import assert_array_equal
from smm_analysis.reproduction import cli, reproduce
from smm_analysis.reproduction.acceptance import acceptance_verdict
from smm_analysis.reproduction.reproduce import (
    REPRODUCTION_CONTROLLERS,
    resolve_controllers,
    resolve_scenarios,
    run_controller,
    run_reproduction,
)
from smm_analysis.reproduction.results import AcceptanceCheck, ReproductionResult
from smm_analysis.reproduction.retuned import (
    FPDESO_RETUNED,
    RETUNED_SETS,
    RetunedSet,
    damping_ratio,
    matched_damping_kd0,
)
from smm_analysis.scenarios import SCENARIOS
from smm_controller.laws import PAPER_LAWS

from smm_analysis import closed_loop
from smm_controller import FPDESOConfig, FPDESOController, TrackingDifferentiatorConfig
from smm_dynamics import SMMParameters

PAPER = FPDESOConfig()


def _flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        flat: dict[str, Any] = {}
        for field in dataclasses.fields(value):
            flat.update(_flatten(getattr(value, field.name), f"{prefix}{field.name}."))
        return flat
    if isinstance(value, tuple):
        return {f"{prefix}{index}": item for index, item in enumerate(value)}
    return {prefix: value}


def test_retuned_set_differs_from_the_papers_only_in_beta_kd0() -> None:
    paper, retuned = _flatten(PAPER), _flatten(FPDESO_RETUNED.config)
    assert paper.keys() == retuned.keys()
    differing = {key for key in paper if paper[key] != retuned[key]}
    assert differing == {"fuzzy.kd0.1"}
    assert PAPER.fuzzy.kd0 == (110.0, 90.0)  # smm_controller's defaults stay the paper's
    assert FPDESO_RETUNED.config.fuzzy.kd0 == (110.0, 111.0)
    assert FPDESO_RETUNED.base == "fpdeso"
    assert "111" in FPDESO_RETUNED.label and "90" in FPDESO_RETUNED.label
    assert RETUNED_SETS == {"fpdeso_retuned": FPDESO_RETUNED}


def test_retuned_beta_kd0_follows_the_alpha_damping_rule_within_rounding() -> None:
    exact = matched_damping_kd0(PAPER)
    assert exact == pytest.approx(110.0 * math.sqrt(4150.0 / 4050.0), rel=1e-14)
    beta_kd0 = FPDESO_RETUNED.config.fuzzy.kd0[1]
    assert beta_kd0 == round(exact)
    kp0, kd0 = FPDESO_RETUNED.config.fuzzy.kp0, FPDESO_RETUNED.config.fuzzy.kd0
    zeta_alpha, zeta_beta = damping_ratio(kp0[0], kd0[0]), damping_ratio(kp0[1], kd0[1])
    rounding = 0.5 / (2.0 * math.sqrt(kp0[1]))  # the change of zeta per 0.5 of k_d0
    assert abs(zeta_beta - zeta_alpha) <= rounding
    assert zeta_beta > damping_ratio(PAPER.fuzzy.kp0[1], PAPER.fuzzy.kd0[1]) + 0.1


def test_matched_damping_kd0_is_the_identity_on_the_source_joint() -> None:
    assert matched_damping_kd0(PAPER, source=1, target=1) == pytest.approx(90.0, rel=1e-14)
    assert damping_ratio(100.0, 20.0) == 1.0


def test_retuned_set_is_a_default_controller_next_to_fpdeso() -> None:
    assert REPRODUCTION_CONTROLLERS[:2] == ("fpdeso", "fpdeso_retuned")
    assert set(REPRODUCTION_CONTROLLERS) == {*PAPER_LAWS, "fpdeso_retuned"}
    assert resolve_controllers(["fpdeso_retuned"]) == ("fpdeso_retuned",)


def test_retuned_run_uses_the_paper_chain_with_only_the_law_replaced(monkeypatch: pytest.MonkeyPatch) -> None:
    """A 'retuned' set carrying the paper's config reproduces the paper's run bit for bit."""
    scenario = SCENARIOS["case2"].with_duration(0.05)
    same = RetunedSet(name="same", base="fpdeso", label="paper copy", config=PAPER, change="", reason="")
    monkeypatch.setattr(reproduce, "RETUNED_SETS", {"same": same})
    copy = run_controller(scenario, "same", seed=3)
    paper = closed_loop.run_closed_loop(scenario, "fpdeso", seed=3)
    assert copy.controller == "same"
    assert_array_equal(copy.command_torque, paper.command_torque)
    assert_array_equal(copy.position, paper.position)


def test_retuned_run_differs_and_is_labelled() -> None:
    scenario = SCENARIOS["step"].with_duration(0.05)
    retuned = run_controller(scenario, "fpdeso_retuned")
    expected = closed_loop.run_closed_loop(
        scenario, "fpdeso", controller=FPDESOController(FPDESO_RETUNED.config, SMMParameters())
    )
    assert retuned.controller == "fpdeso_retuned"
    assert_array_equal(retuned.command_torque, expected.command_torque)
    paper = run_controller(scenario, "fpdeso")
    assert not (retuned.command_torque[:, 1] == paper.command_torque[:, 1]).all()


def test_retuned_set_gets_step_checks_and_stays_out_of_the_case1_ranking() -> None:
    scenarios = resolve_scenarios(["step", "case1"], 0.05)
    result = run_reproduction(scenarios, (PAPER_LAWS[0], "fpdeso_retuned", PAPER_LAWS[1]))
    retuned = [check for check in result.checks if check.controller == "fpdeso_retuned"]
    assert {(check.quantity, check.joint) for check in retuned} == {
        (quantity, joint) for quantity in ("overshoot_fraction", "rise_time") for joint in ("alpha", "beta")
    }
    assert all(check.scenario == "step" and "retuned" in check.claim for check in retuned)
    fpd = result.run("case1", "fpd")
    assert fpd is not None
    for check in result.checks:
        if check.scenario == "case1":
            assert check.controller == "fpdeso"
            assert check.requirement == f"< best other {getattr(fpd.joints[check.joint], check.quantity):.4g}"


def _check(
    quantity: str,
    joint: str,
    value: float,
    passed: bool,
    *,
    controller: str = "fpdeso",
    scenario: str = "step",
) -> AcceptanceCheck:
    return AcceptanceCheck(
        claim=f"{scenario}: {controller} {quantity}",
        scenario=scenario,
        joint=joint,
        value=value,
        requirement="synthetic",
        passed=passed,
        controller=controller,
        quantity=quantity,
    )


def _step_set(controller: str, beta_overshoot: float) -> list[AcceptanceCheck]:
    return [
        _check("overshoot_fraction", "alpha", 0.0046, True, controller=controller),
        _check("rise_time", "alpha", 0.041, True, controller=controller),
        _check("overshoot_fraction", "beta", beta_overshoot, beta_overshoot < 0.05, controller=controller),
        _check("rise_time", "beta", 0.031, True, controller=controller),
    ]


CASES = [
    _check("RMS", "alpha", 0.0023, True, scenario="case1"),
    _check("rms_reduction", "beta", 0.90, True, scenario="case2"),
]


def test_verdict_all_paper_claims_hold() -> None:
    verdict = acceptance_verdict([*_step_set("fpdeso", 0.04), *CASES])
    assert verdict.met and not verdict.failed and not verdict.met_by_retuned
    assert "every acceptance claim holds with the paper's gains" in verdict.message


def test_verdict_paper_step_miss_met_by_the_retuned_set() -> None:
    checks = [*_step_set("fpdeso", 0.0526), *_step_set("fpdeso_retuned", 0.0052), *CASES]
    verdict = acceptance_verdict(checks)
    assert verdict.met and not verdict.failed
    [(paper, retuned)] = verdict.met_by_retuned
    assert (paper.controller, retuned.controller) == ("fpdeso", "fpdeso_retuned")
    assert (paper.quantity, paper.joint) == ("overshoot_fraction", "beta")
    assert (retuned.quantity, retuned.joint) == ("overshoot_fraction", "beta")
    assert "met only with the labelled retuned set" in verdict.message
    assert FPDESO_RETUNED.label in verdict.message
    assert "the paper's gains give 5.26 %" in verdict.message


@pytest.mark.parametrize(
    "checks",
    [
        pytest.param([*_step_set("fpdeso", 0.0526), *CASES], id="paper-step-miss-without-retuned"),
        pytest.param(
            [*_step_set("fpdeso", 0.0526), *_step_set("fpdeso_retuned", 0.06), *CASES],
            id="retuned-also-fails",
        ),
        pytest.param(
            [*_step_set("fpdeso", 0.04), *_step_set("fpdeso_retuned", 0.06), *CASES], id="only-retuned-fails"
        ),
        pytest.param(
            [
                *_step_set("fpdeso", 0.0526),
                *_step_set("fpdeso_retuned", 0.0052),
                _check("RMS", "alpha", 0.03, False, scenario="case1"),
            ],
            id="case1-fails",
        ),
        pytest.param(
            [
                *_step_set("fpdeso", 0.04),
                *_step_set("fpdeso_retuned", 0.0052),
                _check("rms_reduction", "beta", 0.2, False, scenario="case2"),
            ],
            id="case2-fails",
        ),
        pytest.param(
            [
                *_step_set("fpdeso", 0.04)[:2],
                _check("overshoot_fraction", "beta", 0.0526, False),
                _check("overshoot_fraction", "alpha", 0.0052, True, controller="fpdeso_retuned"),
            ],
            id="retuned-meets-another-joint-only",
        ),
    ],
)
def test_verdict_not_met(checks: list[AcceptanceCheck]) -> None:
    verdict = acceptance_verdict(checks)
    assert not verdict.met
    assert verdict.failed
    assert "FAILED" in verdict.message


def _synthetic_result(checks: list[AcceptanceCheck]) -> ReproductionResult:
    return ReproductionResult(
        runs={},
        scenarios=(),
        controllers=("fpdeso", "fpdeso_retuned"),
        seed=0,
        control_period=1e-3,
        td_config=TrackingDifferentiatorConfig(),
        checks=tuple(checks),
    )


@pytest.mark.parametrize(
    ("checks", "code"),
    [
        ([*_step_set("fpdeso", 0.0526), *_step_set("fpdeso_retuned", 0.0052), *CASES], 0),
        ([*_step_set("fpdeso", 0.0526), *CASES], 1),
        ([*_step_set("fpdeso", 0.0526), *_step_set("fpdeso_retuned", 0.07), *CASES], 1),
        (
            [
                *_step_set("fpdeso", 0.0526),
                *_step_set("fpdeso_retuned", 0.0052),
                _check("RMS", "beta", 0.03, False, scenario="case1"),
            ],
            1,
        ),
    ],
)
def test_check_exit_code_and_message(
    checks: list[AcceptanceCheck],
    code: int,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr(cli, "run_reproduction", lambda *args, **kwargs: _synthetic_result(checks))
    assert cli.main(["--check"]) == code
    output = capsys.readouterr().out
    if code == 0:
        assert "verdict: claims met" in output
        assert "met only with the labelled retuned set" in output
    else:
        assert "verdict: claims NOT met" in output
    assert cli.main([]) == 0  # without --check nothing fails
