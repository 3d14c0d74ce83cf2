"""``metrics.json``: one entry per run and the reproduction's document, with its units."""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Final

from smm_analysis.metrics import METRICS, AxisError, Group, JointIndices, StepMetrics, metrics_of
from smm_analysis.reproduction.acceptance import acceptance_verdict
from smm_analysis.reproduction.reproduce import torque_limit_note
from smm_analysis.reproduction.results import JOINTS, ReproductionResult
from smm_analysis.reproduction.retuned import RETUNED_SETS

__all__ = ["METRICS_UNITS", "metrics_document", "run_entry"]


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _units() -> dict[str, str]:
    units = {row.name: row.json_unit for row in METRICS if row.group is not Group.END_EFFECTOR}
    (units["end_effector"],) = {row.json_unit for row in metrics_of(Group.END_EFFECTOR)}
    return units


METRICS_UNITS: Final[Mapping[str, str]] = MappingProxyType(_units())
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
            row.name: getattr(indices, row.name) for row in metrics_of(Group.JOINT)
        }
        if step is not None and joint in step:
            metrics = step[joint]
            values.update(
                {row.name: _finite_or_none(getattr(metrics, row.name)) for row in metrics_of(Group.STEP)}
            )
        entry[joint] = values
    entry["end_effector"] = {
        axis: {row.name: getattr(error, row.name) for row in metrics_of(Group.END_EFFECTOR)}
        for axis, error in end_effector.items()
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
