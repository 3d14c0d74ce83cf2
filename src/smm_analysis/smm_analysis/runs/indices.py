"""SPEC section 5 indices of recorded runs with ``smm_analysis.metrics`` (the module ``smm-reproduce`` uses).

Per joint Ma, Ave, RMS (rad) and eps_u (N^2 m^2 s, of the commanded torque) over the recorded control steps;
end-effector errors (mm); step metrics when the recorded reference is a step (q_d constant, q_d' = q_d'' = 0).
The error is measured on the ground truth where the bag has it (``ground_truth``), else on the measured
position, and every result says which.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from smm_analysis.metrics import (
    CARTESIAN_AXES,
    AxisError,
    Group,
    JointIndices,
    StepMetrics,
    end_effector_errors,
    joint_indices,
    metrics_of,
    step_metrics,
)
from smm_analysis.reproduction.metrics_json import METRICS_UNITS, run_entry
from smm_analysis.runs.latency import summarize_latency
from smm_analysis.runs.recorded import JOINTS, RecordedRun
from smm_dynamics import SMMParameters

__all__ = ["RunMetrics", "comparison_table", "evaluate", "metrics_document", "step_target"]


@dataclass(frozen=True)
class RunMetrics:
    """Indices of one recorded run.

    Attributes:
        run: The run.
        joints: Eq. 42-45 per joint.
        end_effector: Errors along x, y, z (mm).
        step: Step metrics per joint, or None when the reference is not a step.
    """

    run: RecordedRun
    joints: Mapping[str, JointIndices]
    end_effector: Mapping[str, AxisError]
    step: Mapping[str, StepMetrics] | None


def step_target(run: RecordedRun) -> tuple[float, float] | None:
    """The step target (rad) if the recorded reference is a step, else None."""
    desired = run.desired_position
    derivatives = run.reference[:, 1:, :]
    if np.any(derivatives != 0.0) or np.any(desired != desired[0]):
        return None
    if np.all(desired[0] == run.position[0]):
        return None  # a constant reference at the start position is a hold, not a step
    return float(desired[0, 0]), float(desired[0, 1])


def evaluate(run: RecordedRun, params: SMMParameters | None = None) -> RunMetrics:
    """Computes the indices of a recorded run.

    Args:
        run: The run.
        params: Parameters giving the link length for the end-effector errors (default ``SMMParameters()``).

    Returns:
        The metrics.
    """
    model = params if params is not None else SMMParameters()
    target = step_target(run)
    step = None
    if target is not None:
        step = {
            joint: step_metrics(
                run.t_ns, run.position[:, index], target[index], initial=float(run.position[0, index])
            )
            for index, joint in enumerate(JOINTS)
            if target[index] != float(run.position[0, index])
        }
    return RunMetrics(
        run=run,
        joints=joint_indices(run.t_ns, run.desired_position, run.position, run.command_torque),
        end_effector=end_effector_errors(run.t_ns, run.desired_position, run.position, model),
        step=step,
    )


def _run_key(metrics: RunMetrics, taken: set[tuple[str, str]]) -> tuple[str, str]:
    scenario = metrics.run.manifest.scenario or "recorded"
    controller = metrics.run.label
    key = (scenario, controller)
    if key in taken:
        key = (scenario, f"{controller}@{metrics.run.bag.name}")
    taken.add(key)
    return key


def metrics_document(results: Sequence[RunMetrics]) -> dict[str, object]:
    """``metrics.json``'s schema (as ``smm-reproduce`` writes it) for recorded runs.

    ``{scenario: {controller: {"alpha"|"beta": {Ma, Ave, RMS, eps_u, du_rms[, step metrics]},
    "end_effector": {x, y, z: {max_mm, rms_mm}}}}, "meta": {...}}``; the scenario and controller come from
    the run manifest
    (``recorded`` and the bag name when absent). ``meta.bags`` says per bag where the position came from
    (``ground truth`` or ``measured``), how many steps were used and left out, and the loop latency.
    """
    document: dict[str, object] = {}
    bags: dict[str, object] = {}
    taken: set[tuple[str, str]] = set()
    for result in results:
        scenario, controller = _run_key(result, taken)
        per_scenario = document.setdefault(scenario, {})
        assert isinstance(per_scenario, dict)
        entry = run_entry(result.joints, result.step, result.end_effector)
        per_scenario[controller] = entry
        run = result.run
        latency = None if run.latency_ns is None else summarize_latency(run.latency_ns)
        bags[str(run.bag)] = {
            "scenario": scenario,
            "controller": controller,
            "position_source": run.position_source,
            "steps": int(run.t_ns.size),
            "incomplete_steps": run.incomplete_steps,
            "duration_s": float((run.t_ns[-1] - run.t_ns[0]) / 1e9),
            "seed": run.manifest.seed,
            "plant": run.manifest.plant,
            "version": run.manifest.version,
            "latency_ms": None
            if latency is None
            else {"median": latency.p50_ms, "p99": latency.p99_ms, "max": latency.max_ms},
        }
    document["meta"] = {
        "source": "smm-bag analyze",
        "bags": bags,
        "units": {
            **METRICS_UNITS,
            "latency_ms": "ms, receive time of the command minus receive time of its measurement",
        },
    }
    return document


def _number(value: float | None) -> str:
    if value is None or math.isnan(value):
        return "-"
    if math.isinf(value):
        return "not reached"
    return f"{value:.4g}"


def comparison_table(results: Sequence[RunMetrics]) -> str:
    """Side-by-side Markdown table: one column per bag, one row per index."""
    headers = [f"{r.run.label} ({r.run.position_source})" for r in results]
    rows: list[tuple[str, list[str]]] = []
    for joint in JOINTS:
        for metric in metrics_of(Group.JOINT):
            rows.append(
                (
                    f"{joint} {metric.label} ({metric.unit})",
                    [_number(getattr(r.joints[joint], metric.name)) for r in results],
                )
            )
        if any(r.step is not None and joint in r.step for r in results):
            for metric in metrics_of(Group.STEP):
                if not metric.in_reports:
                    continue
                rows.append(
                    (
                        f"{joint} {metric.label} ({metric.unit})",
                        [
                            _number(getattr(r.step[joint], metric.name))
                            if r.step and joint in r.step
                            else "-"
                            for r in results
                        ],
                    )
                )
    for axis in CARTESIAN_AXES:
        for metric in metrics_of(Group.END_EFFECTOR):
            rows.append(
                (
                    f"end effector {axis} {metric.label} ({metric.unit})",
                    [_number(getattr(r.end_effector[axis], metric.name)) for r in results],
                )
            )
    rows.append(("steps", [str(r.run.t_ns.size) for r in results]))
    lines = ["| index | " + " | ".join(headers) + " |", "|---|" + "---|" * len(results)]
    lines.extend(f"| {name} | " + " | ".join(values) + " |" for name, values in rows)
    return "\n".join(lines)
