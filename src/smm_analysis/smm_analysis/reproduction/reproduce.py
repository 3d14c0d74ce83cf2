"""The paper's simulations, every scenario x controller, and their metrics (library of ``smm-reproduce``).

Into ``results``; the claims are in ``acceptance``, ``metrics.json`` in ``metrics_json`` (this package).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence

import numpy as np
from smm_controller.laws import PAPER_LAWS, law_names, law_table
from smm_controller.limits import OutputLimitConfig

from smm_analysis.closed_loop import DEFAULT_CONTROL_PERIOD, Trajectory, run_closed_loop
from smm_analysis.errors import AnalysisError, UnknownControllerError
from smm_analysis.metrics import (
    StepMetrics,
    end_effector_errors,
    joint_indices,
    step_metrics,
)
from smm_analysis.reproduction.acceptance import acceptance_checks
from smm_analysis.reproduction.results import JOINTS, ReproductionResult, RunResult, StepStudyPoint
from smm_analysis.reproduction.retuned import RETUNED_SETS, damping_ratio
from smm_analysis.scenarios import SCENARIOS, Scenario, get_scenario
from smm_controller import FPDESOConfig, TrackingDifferentiatorConfig
from smm_dynamics import SMMParameters

__all__ = [
    "REPRODUCTION_CONTROLLERS",
    "evaluate_run",
    "ideal_step_response",
    "paper_fpdeso_ideal_step",
    "resolve_controllers",
    "resolve_scenarios",
    "run_controller",
    "run_reproduction",
    "step_discretisation_study",
]

REPRODUCTION_CONTROLLERS: tuple[str, ...] = (
    PAPER_LAWS[0],
    *RETUNED_SETS,
    *PAPER_LAWS[1:],
)
"""Default controllers of the reproduction: the paper's, with the labelled retuned sets after FPDESO."""


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
        if name not in law_table() and name not in RETUNED_SETS:
            known = ", ".join((*law_names(), *RETUNED_SETS))
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


def torque_limit_note(result: ReproductionResult) -> tuple[tuple[float, float], float]:
    """``(torque limit (N m) the chains ran with, largest |command| of every run (N m))``."""
    limit = OutputLimitConfig().torque_limit
    peak = max(
        (float(np.max(np.abs(run.trajectory.command_torque))) for run in result.runs.values()), default=0.0
    )
    return limit, peak
