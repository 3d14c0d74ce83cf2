"""The paper's claims checked on a reproduction (step, case 1, case 2) and the verdict in words."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from smm_controller.laws import PAPER_LAWS

from smm_analysis.reproduction.results import JOINTS, AcceptanceCheck, ReproductionResult, RunResult
from smm_analysis.reproduction.retuned import RETUNED_SETS, controller_label

__all__ = [
    "CASE2_RMS_REDUCTION",
    "STEP_OVERSHOOT_LIMIT",
    "STEP_RISE_TIME_RANGE",
    "AcceptanceVerdict",
    "acceptance_checks",
    "acceptance_verdict",
]


STEP_OVERSHOOT_LIMIT = 0.05
"""FPDESO step overshoot must stay below this fraction of the step."""


STEP_RISE_TIME_RANGE: tuple[float, float] = (0.03, 0.09)
"""FPDESO 10-90 % step rise time must lie in this range (s)."""


CASE2_RMS_REDUCTION = 0.38
"""case2: FPDESO's RMS must be at least this fraction below FPD's (the paper: 56 % / 38 %)."""


@dataclass(frozen=True)
class AcceptanceVerdict:
    """The outcome of the acceptance checks, for ``--check`` and the report.

    Attributes:
        met: Every claim holds with the paper's gains, or the only failures are step claims of the
            paper's FPDESO gains that a labelled retuned set meets.
        failed: Checks that fail and are not met by a retuned set (their own failures included).
        met_by_retuned: (paper check, retuned check) pairs: a step claim the paper's gains miss and the
            labelled retuned set meets.
        message: One line per finding, in words.
    """

    met: bool
    failed: tuple[AcceptanceCheck, ...]
    met_by_retuned: tuple[tuple[AcceptanceCheck, AcceptanceCheck], ...]
    message: str


def _step_checks(run: RunResult, controller: str) -> list[AcceptanceCheck]:
    assert run.step is not None
    label = controller_label(controller)
    low, high = STEP_RISE_TIME_RANGE
    checks = []
    for joint in JOINTS:
        metrics = run.step[joint]
        overshoot, rise = metrics.overshoot_fraction, metrics.rise_time
        claims = (
            (
                "overshoot (fraction of the step)",
                "overshoot_fraction",
                overshoot,
                f"< {STEP_OVERSHOOT_LIMIT:g}",
                overshoot < STEP_OVERSHOOT_LIMIT,
            ),
            ("10-90 % rise time (s)", "rise_time", rise, f"in [{low:g}, {high:g}]", low <= rise <= high),
        )
        for claim, quantity, value, requirement, passed in claims:
            checks.append(
                AcceptanceCheck(
                    claim=f"step: {label} {claim}",
                    scenario="step",
                    joint=joint,
                    value=value,
                    requirement=requirement,
                    passed=passed,
                    controller=controller,
                    quantity=quantity,
                )
            )
    return checks


def acceptance_checks(result: ReproductionResult) -> list[AcceptanceCheck]:
    """Evaluates the acceptance claims whose runs are present in ``result``.

    The step claims are checked on the paper's FPDESO gains and, separately, on every retuned FPDESO
    set run; the case1 and case2 claims only on the paper's gains (the retuned sets are not among the
    'other controllers' of case1).

    Returns:
        One check per claim, gain set and joint; claims whose runs are missing are left out.
    """
    checks: list[AcceptanceCheck] = []
    step_sets = ["fpdeso"] + [
        name for name in result.controllers if name in RETUNED_SETS and RETUNED_SETS[name].base == "fpdeso"
    ]
    for controller in step_sets:
        step = result.run("step", controller)
        if step is not None and step.step is not None:
            checks += _step_checks(step, controller)
    paper_controllers = [name for name in result.controllers if name in PAPER_LAWS]
    case1 = {name: result.run("case1", name) for name in paper_controllers}
    if case1.get("fpdeso") is not None and len([run for run in case1.values() if run is not None]) > 1:
        for metric in ("RMS", "Ma"):
            for joint in JOINTS:
                values = {
                    name: getattr(run.joints[joint], metric) for name, run in case1.items() if run is not None
                }
                best_other = min(value for name, value in values.items() if name != "fpdeso")
                checks.append(
                    AcceptanceCheck(
                        claim=f"case1: FPDESO has the lowest {metric} (rad)",
                        scenario="case1",
                        joint=joint,
                        value=values["fpdeso"],
                        requirement=f"< best other {best_other:.4g}",
                        passed=values["fpdeso"] < best_other,
                        quantity=metric,
                    )
                )
    fpdeso2, fpd2 = result.run("case2", "fpdeso"), result.run("case2", "fpd")
    if fpdeso2 is not None and fpd2 is not None:
        for joint in JOINTS:
            reduction = 1.0 - fpdeso2.joints[joint].RMS / fpd2.joints[joint].RMS
            checks.append(
                AcceptanceCheck(
                    claim="case2: FPDESO RMS reduction versus FPD (fraction)",
                    scenario="case2",
                    joint=joint,
                    value=reduction,
                    requirement=f">= {CASE2_RMS_REDUCTION:g}",
                    passed=reduction >= CASE2_RMS_REDUCTION,
                    quantity="rms_reduction",
                )
            )
        for joint in JOINTS:
            energy, fpd_energy = fpdeso2.joints[joint].eps_u, fpd2.joints[joint].eps_u
            checks.append(
                AcceptanceCheck(
                    claim="case2: FPDESO control energy eps_u below FPD's (N^2 m^2 s)",
                    scenario="case2",
                    joint=joint,
                    value=energy,
                    requirement=f"< FPD {fpd_energy:.4g}",
                    passed=energy < fpd_energy,
                    quantity="eps_u",
                )
            )
    return checks


def _check_value_text(check: AcceptanceCheck) -> str:
    if check.quantity == "overshoot_fraction":
        return f"{100 * check.value:.2f} %"
    if check.quantity == "rise_time":
        return f"{check.value:.3f} s"
    return f"{check.value:.4g}"


def _requirement_text(check: AcceptanceCheck) -> str:
    if check.quantity == "overshoot_fraction":
        return f"< {100 * STEP_OVERSHOOT_LIMIT:g} %"
    if check.quantity == "rise_time":
        low, high = STEP_RISE_TIME_RANGE
        return f"in [{low:g}, {high:g}] s"
    return check.requirement


def acceptance_verdict(checks: Sequence[AcceptanceCheck]) -> AcceptanceVerdict:
    """Decides whether the acceptance claims are met and says by which gain set.

    Met when every check of the paper's gains passes, or when the only failures are step checks of the
    paper's FPDESO gains that the same check (quantity and joint) of a labelled retuned FPDESO set
    passes. A failing check of a retuned set, or of a case1/case2 claim, is never excused.

    Args:
        checks: The checks (:func:`acceptance_checks`).

    Returns:
        The verdict with a message naming which set met what.
    """
    retuned_checks = {
        (check.scenario, check.quantity, check.joint): check
        for check in checks
        if check.controller in RETUNED_SETS and RETUNED_SETS[check.controller].base == "fpdeso"
    }
    failed: list[AcceptanceCheck] = []
    met_by_retuned: list[tuple[AcceptanceCheck, AcceptanceCheck]] = []
    for check in checks:
        if check.passed:
            continue
        rescue = retuned_checks.get((check.scenario, check.quantity, check.joint))
        if check.controller == "fpdeso" and check.scenario == "step" and rescue is not None and rescue.passed:
            met_by_retuned.append((check, rescue))
        else:
            failed.append(check)
    lines = []
    for paper, retuned in met_by_retuned:
        lines.append(
            f"step claim ({paper.quantity.replace('_', ' ')}, {paper.joint}) met only with the labelled "
            f"retuned set '{controller_label(retuned.controller)}' ({_check_value_text(retuned)}); the "
            f"paper's gains give {_check_value_text(paper)} (requirement {_requirement_text(paper)})"
        )
    for check in failed:
        lines.append(
            f"FAILED: {check.claim}, {check.joint}: {_check_value_text(check)} "
            f"(requirement {_requirement_text(check)})"
        )
    if not lines:
        lines.append("every acceptance claim holds with the paper's gains" if checks else "no claim checked")
    return AcceptanceVerdict(
        met=not failed,
        failed=tuple(failed),
        met_by_retuned=tuple(met_by_retuned),
        message="\n".join(lines),
    )
