"""SPEC section 5 indices of recorded runs with ``smm_analysis.metrics`` (the module ``smm-reproduce`` uses).

Per joint Ma, Ave, RMS (rad) and eps_u (N^2 m^2 s, of the commanded torque) over the recorded control steps;
end-effector errors (mm); step metrics when the recorded reference is a step (q_d constant, q_d' = q_d'' = 0).
The error is measured on the ground truth where the bag has it (``ground_truth``), else on the measured
position, and every result says which.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from smm_bag.manifest import RunManifest

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
from smm_analysis.runs.accumulate import IndexAccumulator
from smm_analysis.runs.latency import LatencySketch, LatencySummary, summarize_latency
from smm_analysis.runs.recorded import JOINTS, RecordedRun
from smm_analysis.runs.stream import StepBlock, StepStream
from smm_dynamics import SMMParameters

__all__ = [
    "RunMetrics",
    "RunSummary",
    "comparison_table",
    "evaluate",
    "evaluate_stream",
    "metrics_document",
    "step_target",
]


@dataclass(frozen=True)
class RunSummary:
    """What the indices were computed on: the bag, its manifest, the steps used and left out, the latency.

    Attributes:
        bag: Bag folder.
        manifest: Run manifest.
        label: Name of the run in tables (controller, or bag name; a segment's number appended).
        position_source: ``"ground truth"`` or ``"measured"``.
        steps: Steps used.
        incomplete_steps: Stamps seen on some required topics but not all (left out).
        first_ns: First step's stamp (ns).
        last_ns: Last step's stamp (ns).
        latency: Loop latency quantiles (ms), or None when not known.
        late_messages: Per topic, messages that came after the reorder window (left out).
        ahead_messages: Per topic, messages stamped far after their log time (left out; ``AHEAD_LIMIT_NS``).
        window: ``--start A --end B`` that selects these steps (empty: the whole bag).
    """

    bag: Path
    manifest: RunManifest
    label: str
    position_source: str
    steps: int
    incomplete_steps: int
    first_ns: int
    last_ns: int
    latency: LatencySummary | None
    late_messages: Mapping[str, int] = field(default_factory=dict)
    ahead_messages: Mapping[str, int] = field(default_factory=dict)
    window: str = ""

    @property
    def duration_s(self) -> float:
        """Last step minus first step (s)."""
        return (self.last_ns - self.first_ns) / 1e9


@dataclass(frozen=True)
class RunMetrics:
    """Indices of one recorded run.

    Attributes:
        run: What they were computed on.
        joints: Eq. 42-45 per joint.
        end_effector: Errors along x, y, z (mm).
        step: Step metrics per joint, or None when the reference is not a step.
    """

    run: RunSummary
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
    summary = RunSummary(
        bag=run.bag,
        manifest=run.manifest,
        label=run.label,
        position_source=run.position_source,
        steps=int(run.t_ns.size),
        incomplete_steps=run.incomplete_steps,
        first_ns=int(run.t_ns[0]),
        last_ns=int(run.t_ns[-1]),
        latency=None if run.latency_ns is None else summarize_latency(run.latency_ns),
    )
    return RunMetrics(
        run=summary,
        joints=joint_indices(run.t_ns, run.desired_position, run.position, run.command_torque),
        end_effector=end_effector_errors(run.t_ns, run.desired_position, run.position, model),
        step=step,
    )


def evaluate_stream(
    stream: StepStream,
    params: SMMParameters | None = None,
    *,
    consumers: Sequence[Callable[[StepBlock], None]] = (),
    label: str | None = None,
) -> RunMetrics:
    """Computes the indices of a bag read once in blocks (bounded memory), as :func:`evaluate` does in memory.

    Args:
        stream: The bag's joined steps (its window chosen).
        params: Parameters giving the link length (default ``SMMParameters()``).
        consumers: Also given every block (figures).
        label: Name in tables (default: the stream's).

    Raises:
        BagError: See :class:`StepStream`.
        MetricsInputError: A non-finite recorded value.
    """
    indices = IndexAccumulator(params)
    latency = LatencySketch()
    for block in stream.blocks():
        indices.add(block)
        latency.add(block.latency_ns)
        for consume in consumers:
            consume(block)
    result = indices.result()
    report = stream.report
    summary = RunSummary(
        bag=stream.bag,
        manifest=stream.manifest,
        label=label if label is not None else stream.label,
        position_source=stream.position_source,
        steps=result.steps,
        incomplete_steps=report.incomplete_steps,
        first_ns=result.first_ns,
        last_ns=result.last_ns,
        latency=latency.summary(),
        late_messages=dict(report.late_messages),
        ahead_messages=dict(report.ahead_messages),
        window=stream.window.describe(),
    )
    return RunMetrics(run=summary, joints=result.joints, end_effector=result.end_effector, step=result.step)


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
        latency = run.latency
        name = str(run.bag) if not run.window else f"{run.bag} {run.window}"
        bags[name] = {
            "scenario": scenario,
            "controller": controller,
            "position_source": run.position_source,
            "steps": run.steps,
            "incomplete_steps": run.incomplete_steps,
            "late_messages": dict(run.late_messages),
            "ahead_messages": dict(run.ahead_messages),
            "window": run.window,
            "duration_s": run.duration_s,
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
    rows.append(("steps", [str(r.run.steps) for r in results]))
    lines = ["| index | " + " | ".join(headers) + " |", "|---|" + "---|" * len(results)]
    lines.extend(f"| {name} | " + " | ".join(values) + " |" for name, values in rows)
    return "\n".join(lines)
