"""Reproduction of the paper's simulations: every scenario x controller, metrics, acceptance checks.

Library layer of ``smm-reproduce``: functions take data and return data, raise the typed errors of
:mod:`smm_analysis.errors`, and print nothing (progress goes through a callback).

Acceptance claims checked (see :func:`acceptance_checks`):

* step: FPDESO overshoot < 5 % and 10-90 % rise time in [0.03, 0.09] s, on both joints;
* case1: FPDESO has the lowest RMS and the lowest M_a of all controllers run, on both joints;
* case2: FPDESO's RMS is at least 38 % below FPD's, on both joints.

The claims are checked on the paper's FPDESO gains. The clearly labelled retuned sets of
:mod:`smm_analysis.retuned` run beside the paper's as pseudo-controllers (``fpdeso_retuned``) and get the
step checks too; :func:`acceptance_verdict` accepts a failed step claim of the paper's gains only if the
retuned set meets it, and says so.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Final

import numpy as np
from smm_controller.limits import OutputLimitConfig

from smm_analysis.closed_loop import DEFAULT_CONTROL_PERIOD, Trajectory, run_closed_loop
from smm_analysis.errors import AnalysisError, UnknownControllerError
from smm_analysis.metrics import (
    AxisError,
    JointIndices,
    StepMetrics,
    end_effector_errors,
    joint_indices,
    step_metrics,
)
from smm_analysis.retuned import RETUNED_SETS, damping_ratio
from smm_analysis.scenarios import SCENARIOS, Scenario, get_scenario
from smm_controller import CONTROLLER_NAMES, FPDESOConfig, TrackingDifferentiatorConfig
from smm_dynamics import SMMParameters

__all__ = [
    "CASE2_RMS_REDUCTION",
    "JOINTS",
    "METRICS_UNITS",
    "REPRODUCTION_CONTROLLERS",
    "STEP_OVERSHOOT_LIMIT",
    "STEP_RISE_TIME_RANGE",
    "AcceptanceCheck",
    "AcceptanceVerdict",
    "ReproductionResult",
    "RunResult",
    "StepStudyPoint",
    "acceptance_checks",
    "acceptance_verdict",
    "controller_label",
    "evaluate_run",
    "ideal_step_response",
    "metrics_document",
    "paper_fpdeso_ideal_step",
    "resolve_controllers",
    "resolve_scenarios",
    "run_controller",
    "run_entry",
    "run_reproduction",
    "step_discretisation_study",
]

JOINTS: tuple[str, str] = ("alpha", "beta")
STEP_OVERSHOOT_LIMIT = 0.05
"""FPDESO step overshoot must stay below this fraction of the step."""
STEP_RISE_TIME_RANGE: tuple[float, float] = (0.03, 0.09)
"""FPDESO 10-90 % step rise time must lie in this range (s)."""
CASE2_RMS_REDUCTION = 0.38
"""case2: FPDESO's RMS must be at least this fraction below FPD's (the paper: 56 % / 38 %)."""
REPRODUCTION_CONTROLLERS: tuple[str, ...] = (
    CONTROLLER_NAMES[0],
    *RETUNED_SETS,
    *CONTROLLER_NAMES[1:],
)
"""Default controllers of the reproduction: the paper's, with the labelled retuned sets after FPDESO."""

_PAPER_LABELS = {"fpdeso": "FPDESO", "fpd": "FPD", "pid": "PID", "npd": "NPD"}


@dataclass(frozen=True, eq=False)
class RunResult:
    """Metrics of one scenario x controller run.

    Attributes:
        scenario: Scenario name.
        controller: Controller name.
        joints: Eq. 42-45 per joint (error on the true position, energy of the commanded torque).
        step: Step metrics per joint (step scenarios only).
        end_effector: End-effector errors along x, y, z (mm).
        wall_time: Wall-clock time of the run (s), for the progress line only.
        trajectory: The sampled run (for plots).
    """

    scenario: str
    controller: str
    joints: Mapping[str, JointIndices]
    step: Mapping[str, StepMetrics] | None
    end_effector: Mapping[str, AxisError]
    wall_time: float
    trajectory: Trajectory


@dataclass(frozen=True)
class AcceptanceCheck:
    """One acceptance claim on one joint.

    Attributes:
        claim: What is claimed, in words.
        scenario: Scenario name.
        joint: ``alpha`` or ``beta``.
        value: The measured quantity (unit in ``claim``).
        requirement: The bound, in words.
        passed: Whether the claim holds.
        controller: The controller (gain set) the claim is checked on: ``"fpdeso"`` for the paper's
            gains, or a retuned set's name.
        quantity: What ``value`` is: ``overshoot_fraction``, ``rise_time``, ``RMS``, ``Ma``,
            ``rms_reduction`` or ``eps_u``; matches a retuned set's check with the paper set's.
    """

    claim: str
    scenario: str
    joint: str
    value: float
    requirement: str
    passed: bool
    controller: str = "fpdeso"
    quantity: str = ""


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


@dataclass(frozen=True)
class StepStudyPoint:
    """FPDESO step response under one variation of the discretisation.

    Attributes:
        label: The variation (control period, TD filter factor, sub-steps).
        step: Step metrics per joint.
    """

    label: str
    step: Mapping[str, StepMetrics]


@dataclass(frozen=True, eq=False)
class ReproductionResult:
    """Everything ``smm-reproduce`` computed.

    Attributes:
        runs: Results by (scenario, controller), in run order.
        scenarios: Scenarios run, in order.
        controllers: Controllers run, in order.
        seed: Noise seed.
        control_period: Control period (s).
        td_config: TD parameters used by every chain.
        checks: Acceptance checks (those whose runs are present).
        step_study: FPDESO step metrics versus control period (empty if not computed).
    """

    runs: Mapping[tuple[str, str], RunResult]
    scenarios: tuple[Scenario, ...]
    controllers: tuple[str, ...]
    seed: int
    control_period: float
    td_config: TrackingDifferentiatorConfig
    checks: tuple[AcceptanceCheck, ...] = ()
    step_study: tuple[StepStudyPoint, ...] = field(default_factory=tuple)

    def run(self, scenario: str, controller: str) -> RunResult | None:
        """The result of one run, or None if it was not run."""
        return self.runs.get((scenario, controller))


def resolve_scenarios(names: Sequence[str], duration: float | None = None) -> tuple[Scenario, ...]:
    """Scenarios by name, optionally all shortened to ``duration`` (s).

    Raises:
        UnknownScenarioError: A name is unknown.
        AnalysisError: No name, a duplicate, or a bad duration.
    """
    if not names:
        raise AnalysisError("at least one scenario is needed")
    if len(set(names)) != len(names):
        raise AnalysisError(f"duplicate scenario in {list(names)}")
    scenarios = tuple(get_scenario(name) for name in names)
    if duration is None:
        return scenarios
    if not (math.isfinite(duration) and duration > 0.0):
        raise AnalysisError(f"duration must be a finite number > 0 s, got {duration!r}")
    return tuple(scenario.with_duration(duration) for scenario in scenarios)


def controller_label(name: str) -> str:
    """Human label of a controller or retuned set (``FPDESO``, ``FPDESO, retuned (...)``)."""
    if name in RETUNED_SETS:
        return RETUNED_SETS[name].label
    return _PAPER_LABELS.get(name, name)


def resolve_controllers(names: Sequence[str]) -> tuple[str, ...]:
    """Validated controller names: the paper's controllers and the retuned sets' pseudo-names.

    Raises:
        UnknownControllerError: A name is unknown.
        AnalysisError: No name or a duplicate.
    """
    if not names:
        raise AnalysisError("at least one controller is needed")
    if len(set(names)) != len(names):
        raise AnalysisError(f"duplicate controller in {list(names)}")
    for name in names:
        if name not in CONTROLLER_NAMES and name not in RETUNED_SETS:
            known = ", ".join((*CONTROLLER_NAMES, *RETUNED_SETS))
            raise UnknownControllerError(f"unknown controller {name!r}; known: {known}")
    return tuple(names)


def run_controller(
    scenario: Scenario,
    name: str,
    *,
    seed: int = 0,
    control_period: float = DEFAULT_CONTROL_PERIOD,
    td_config: TrackingDifferentiatorConfig | None = None,
) -> Trajectory:
    """One closed-loop run of a paper controller or a retuned set (labelled with ``name``).

    Args:
        scenario: The scenario.
        name: A paper controller name or a retuned set's pseudo-name.
        seed: Noise seed.
        control_period: Control period (s).
        td_config: TD parameters (default: ``smm_controller``'s defaults).

    Returns:
        The run; ``trajectory.controller`` is ``name``.
    """
    retuned = RETUNED_SETS.get(name)
    if retuned is None:
        return run_closed_loop(scenario, name, seed=seed, control_period=control_period, td_config=td_config)
    model_params = SMMParameters()
    trajectory = run_closed_loop(
        scenario,
        retuned.base,
        seed=seed,
        control_period=control_period,
        td_config=td_config,
        controller=retuned.make_controller(model_params),
        model_params=model_params,
    )
    return dataclasses.replace(trajectory, controller=name)


def _step_metrics_of(trajectory: Trajectory, scenario: Scenario) -> dict[str, StepMetrics]:
    return {
        joint: step_metrics(trajectory.t_ns, trajectory.position[:, index], scenario.amplitude[index])
        for index, joint in enumerate(JOINTS)
    }


def evaluate_run(trajectory: Trajectory, scenario: Scenario, wall_time: float = 0.0) -> RunResult:
    """Computes the metrics of a finished run.

    Args:
        trajectory: The run.
        scenario: Its scenario (decides whether step metrics apply).
        wall_time: Wall-clock time the run took (s).

    Returns:
        The run's metrics.
    """
    return RunResult(
        scenario=trajectory.scenario,
        controller=trajectory.controller,
        joints=joint_indices(
            trajectory.t_ns, trajectory.desired_position, trajectory.position, trajectory.command_torque
        ),
        step=_step_metrics_of(trajectory, scenario) if scenario.is_step else None,
        end_effector=end_effector_errors(
            trajectory.t_ns, trajectory.desired_position, trajectory.position, trajectory.plant_params
        ),
        wall_time=wall_time,
        trajectory=trajectory,
    )


def run_reproduction(
    scenarios: Sequence[Scenario] = tuple(SCENARIOS.values()),
    controllers: Sequence[str] = REPRODUCTION_CONTROLLERS,
    *,
    seed: int = 0,
    control_period: float = DEFAULT_CONTROL_PERIOD,
    td_config: TrackingDifferentiatorConfig | None = None,
    step_study: bool = False,
    progress: Callable[[RunResult, int, int], None] | None = None,
) -> ReproductionResult:
    """Runs every scenario with every controller and evaluates the acceptance claims.

    Args:
        scenarios: Scenarios to run.
        controllers: Controller names to run (paper controllers and retuned sets' pseudo-names).
        seed: Noise seed of every run.
        control_period: Control period (s).
        td_config: TD parameters (default: ``smm_controller``'s defaults).
        step_study: Also run :func:`step_discretisation_study` (about 10 s).
        progress: Called after each run with (result, index starting at 1, total).

    Returns:
        All results.
    """
    td = td_config if td_config is not None else TrackingDifferentiatorConfig()
    chosen = resolve_controllers(list(controllers))
    runs: dict[tuple[str, str], RunResult] = {}
    total = len(scenarios) * len(chosen)
    for scenario in scenarios:
        for controller in chosen:
            start = time.perf_counter()
            trajectory = run_controller(
                scenario, controller, seed=seed, control_period=control_period, td_config=td
            )
            result = evaluate_run(trajectory, scenario, time.perf_counter() - start)
            runs[(scenario.name, controller)] = result
            if progress is not None:
                progress(result, len(runs), total)
    study = step_discretisation_study(control_period=control_period, seed=seed) if step_study else []
    partial = ReproductionResult(
        runs=runs,
        scenarios=tuple(scenarios),
        controllers=chosen,
        seed=seed,
        control_period=control_period,
        td_config=td,
        step_study=tuple(study),
    )
    return dataclasses.replace(partial, checks=tuple(acceptance_checks(partial)))


def step_discretisation_study(
    *, control_period: float = DEFAULT_CONTROL_PERIOD, seed: int = 0
) -> list[StepStudyPoint]:
    """FPDESO on the step scenario under variations of the discretisation.

    Variations: TD filter factor h in {1, 2, 3} x dt, 8 RK4 sub-steps instead of 1, and control periods
    dt / 2 and dt / 10 (with h = period). Shows how far the sampled loop's overshoot is from the
    continuous-time ideal of :func:`ideal_step_response` and what it depends on.

    Args:
        control_period: Base control period dt (s); 1 s must be a multiple of dt / 10.
        seed: Noise seed (the step scenario has no noise).

    Returns:
        One point per variation, labelled.
    """
    scenario = SCENARIOS["step"]
    variations: list[tuple[str, float, float, int]] = [
        (f"dt {1e3 * control_period:g} ms, h = {factor} dt", control_period, factor * control_period, 1)
        for factor in (1, 2, 3)
    ]
    variations.append(
        (f"dt {1e3 * control_period:g} ms, h = dt, 8 RK4 sub-steps", control_period, control_period, 8)
    )
    for divisor in (2, 10):
        period = control_period / divisor
        variations.append((f"dt {1e3 * period:g} ms, h = dt", period, period, 1))
    points = []
    for label, period, factor, substeps in variations:
        # sigma large enough that the TD stays in its linear zone (|y| < h^2 sigma) once it has locked on.
        speed = max(1.0e5, 0.1 / factor**2)
        td = TrackingDifferentiatorConfig(speed=(speed, speed), filter_factor=(factor, factor))
        trajectory = run_closed_loop(
            scenario,
            "fpdeso",
            seed=seed,
            control_period=period,
            td_config=td,
            substeps=substeps,
            record_internals=False,
        )
        points.append(StepStudyPoint(label=label, step=_step_metrics_of(trajectory, scenario)))
    return points


def ideal_step_response(kp: float, kd: float) -> tuple[float, float]:
    """Overshoot fraction and 10-90 % rise time of the unit step response of e'' + kd e' + kp e = 0.

    That is the FPDESO loop with an exact model, in continuous time, with fixed gains.

    Args:
        kp: Proportional gain (1/s^2), > 0.
        kd: Derivative gain (1/s), > 0.

    Returns:
        (overshoot fraction, rise time in s); the crossing times are found by bisection.
    """
    if not (kp > 0.0 and kd > 0.0):
        raise AnalysisError(f"kp and kd must be > 0, got {kp!r}, {kd!r}")
    omega = math.sqrt(kp)
    zeta = damping_ratio(kp, kd)
    overshoot = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta * zeta)) if zeta < 1.0 else 0.0

    def unit_response(t: float) -> float:
        if zeta < 1.0:
            damped = omega * math.sqrt(1.0 - zeta * zeta)
            phase = math.acos(zeta)
            return 1.0 - math.exp(-zeta * omega * t) * math.sin(damped * t + phase) / math.sqrt(
                1.0 - zeta * zeta
            )
        if zeta == 1.0:
            return 1.0 - (1.0 + omega * t) * math.exp(-omega * t)
        root = math.sqrt(zeta * zeta - 1.0)
        fast, slow = omega * (zeta + root), omega * (zeta - root)
        return 1.0 + (slow * math.exp(-fast * t) - fast * math.exp(-slow * t)) / (fast - slow)

    def crossing(level: float) -> float:
        low, high = 0.0, 1.0 / omega
        while unit_response(high) < level:
            high *= 2.0
        for _ in range(80):
            middle = 0.5 * (low + high)
            if unit_response(middle) < level:
                low = middle
            else:
                high = middle
        return 0.5 * (low + high)

    return overshoot, crossing(0.9) - crossing(0.1)


def paper_fpdeso_ideal_step() -> dict[str, tuple[float, float]]:
    """:func:`ideal_step_response` with the paper's FPDESO k_p0, k_d0 per joint."""
    fuzzy = FPDESOConfig().fuzzy
    return {
        joint: ideal_step_response(fuzzy.kp0[index], fuzzy.kd0[index]) for index, joint in enumerate(JOINTS)
    }


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
    paper_controllers = [name for name in result.controllers if name in CONTROLLER_NAMES]
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


def torque_limit_note(result: ReproductionResult) -> tuple[tuple[float, float], float]:
    """``(torque limit (N m) the chains ran with, largest |command| of every run (N m))``."""
    limit = OutputLimitConfig().torque_limit
    peak = max(
        (float(np.max(np.abs(run.trajectory.command_torque))) for run in result.runs.values()), default=0.0
    )
    return limit, peak


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


METRICS_UNITS: Final[Mapping[str, str]] = MappingProxyType(
    {
        "Ma": "rad",
        "Ave": "rad",
        "RMS": "rad",
        "eps_u": "N^2 m^2 s (integral of the commanded torque squared)",
        "du_rms": "N m per control step (RMS of the commanded torque's increment; torque smoothness)",
        "rise_time": "s (10-90 %)",
        "overshoot": "rad",
        "overshoot_fraction": "fraction of the step (x100 = %)",
        "settling_time": "s (2 % band; null = not settled)",
        "end_effector": "mm",
    }
)
"""Units of the quantities of :func:`run_entry` (``meta.units`` of ``metrics.json``)."""


def run_entry(
    joints: Mapping[str, JointIndices],
    step: Mapping[str, StepMetrics] | None,
    end_effector: Mapping[str, AxisError],
) -> dict[str, object]:
    """One run of ``metrics.json``: per joint the indices (and step metrics), and ``end_effector``."""
    entry: dict[str, object] = {}
    for joint in JOINTS:
        indices = joints[joint]
        values: dict[str, float | None] = {
            "Ma": indices.Ma,
            "Ave": indices.Ave,
            "RMS": indices.RMS,
            "eps_u": indices.eps_u,
            "du_rms": indices.du_rms,
        }
        if step is not None and joint in step:
            metrics = step[joint]
            values.update(
                {
                    "rise_time": _finite_or_none(metrics.rise_time),
                    "overshoot": metrics.overshoot,
                    "overshoot_fraction": metrics.overshoot_fraction,
                    "settling_time": _finite_or_none(metrics.settling_time),
                }
            )
        entry[joint] = values
    entry["end_effector"] = {
        axis: {"max_mm": error.max_mm, "rms_mm": error.rms_mm} for axis, error in end_effector.items()
    }
    return entry


def metrics_document(result: ReproductionResult) -> dict[str, object]:
    """The JSON document written to metrics.json.

    Schema: ``{scenario: {controller: {"alpha"|"beta": {...}, "end_effector": {...}}}}`` plus three
    reserved top-level keys, ``"acceptance"`` (list of checks, each naming the gain set it was checked
    on), ``"acceptance_verdict"`` (``{"met": bool, "message": str}``, see :func:`acceptance_verdict`) and
    ``"meta"`` (run settings, units and the retuned sets run, with their labels and changes).
    Controllers include the retuned sets' pseudo-names (``fpdeso_retuned``).
    Per joint: Ma, Ave, RMS (rad), eps_u (N^2 m^2 s), du_rms (N m per step); for step scenarios also
    rise_time (s), overshoot (rad), overshoot_fraction (of the step) and settling_time (s; null = not
    settled by the end).
    ``end_effector``: x, y, z each {max_mm, rms_mm}.
    """
    document: dict[str, object] = {}
    for (scenario, controller), run in result.runs.items():
        per_scenario = document.setdefault(scenario, {})
        assert isinstance(per_scenario, dict)
        entry = run_entry(run.joints, run.step, run.end_effector)
        per_scenario[controller] = entry
    document["acceptance"] = [
        {
            "claim": check.claim,
            "scenario": check.scenario,
            "joint": check.joint,
            "value": _finite_or_none(check.value),
            "requirement": check.requirement,
            "passed": check.passed,
            "controller": check.controller,
            "quantity": check.quantity,
        }
        for check in result.checks
    ]
    verdict = acceptance_verdict(result.checks)
    document["acceptance_verdict"] = {"met": verdict.met, "message": verdict.message}
    limit, peak = torque_limit_note(result)
    document["meta"] = {
        "torque_limit_Nm": list(limit),
        "peak_command_Nm": peak,
        "seed": result.seed,
        "control_period_s": result.control_period,
        "td_speed": list(result.td_config.speed),
        "td_filter_factor_s": list(result.td_config.filter_factor),
        "scenarios": {
            scenario.name: {"duration_s": scenario.duration, "description": scenario.description}
            for scenario in result.scenarios
        },
        "controllers": list(result.controllers),
        "retuned_sets": {
            name: {
                "label": RETUNED_SETS[name].label,
                "base": RETUNED_SETS[name].base,
                "change": RETUNED_SETS[name].change,
                "reason": RETUNED_SETS[name].reason,
                "kp0": list(RETUNED_SETS[name].config.fuzzy.kp0),
                "kd0": list(RETUNED_SETS[name].config.fuzzy.kd0),
            }
            for name in result.controllers
            if name in RETUNED_SETS
        },
        "units": dict(METRICS_UNITS),
    }
    return document
