"""What a finished sweep shows: robustness statistics per gain set, the Pareto front, the chosen set.

Per gain set and index column, over its plant draws: P50, P95 and the worst (largest; a diverged run
counts as +inf). The Pareto front is over the gain sets, on the spec's objectives (all minimised) taken
at the spec's statistic. The chosen set meets every constraint (at that statistic) and has the least
``select``; when none meets them all, the closest one (least sum of relative misses) is reported with
what it misses, by how much.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray
from smm_controller.laws import law_table
from smm_controller.limits import OutputLimitConfig

from smm_analysis.batch.loop import INDEX_NAMES, RunSettings, run_batch
from smm_analysis.closed_loop import scenario_plant_config
from smm_analysis.sweep.spec import Constraint, SweepSpec
from smm_controller import FLESOConfig, TrackingDifferentiatorConfig
from smm_dynamics import SMMParameters

__all__ = ["ConstraintResult", "SweepResult", "analyse", "pareto_mask", "runs_table"]

FloatArray = NDArray[np.float64]
_STATISTICS = {"p50": 50.0, "p95": 95.0}


def _flat(prefix: str, values: Mapping[str, object]) -> dict[str, object]:
    result: dict[str, object] = {}
    for name, value in values.items():
        if isinstance(value, (list, tuple)):
            for index, item in enumerate(value):
                result[f"{prefix}{name}[{index}]"] = item
        else:
            result[f"{prefix}{name}"] = value
    return result


def runs_table(spec: SweepSpec, indices: pa.Table) -> pa.Table:
    """Every run's settings (varied gains, plant draw values, seed) and indices, one row per run id."""
    run_ids = indices.column("run_id").to_pylist()
    rows: dict[str, list[object]] = {
        "run_id": [],
        "gain_set": [],
        "plant_draw": [],
        "scenario": [],
        "seed": [],
    }
    settings_columns: dict[str, list[object]] = {}
    for position, run_id in enumerate(run_ids):
        gain_set, draw, scenario = spec.locate(run_id)
        rows["run_id"].append(run_id)
        rows["gain_set"].append(gain_set)
        rows["plant_draw"].append(draw)
        rows["scenario"].append(spec.scenarios[scenario].name)
        rows["seed"].append(spec.settings(run_id).plant.seed)
        values = {**_flat("gain.", spec.gain_sets[gain_set]), **_flat("plant.", spec.plant_draws[draw])}
        for name, value in values.items():
            settings_columns.setdefault(name, [None] * len(run_ids))[position] = value
    columns: dict[str, object] = {**rows, **settings_columns}
    for name in INDEX_NAMES:
        columns[name] = indices.column(name)
    return pa.table(columns)


def pareto_mask(points: FloatArray) -> NDArray[np.bool_]:
    """Rows of ``points`` (minimised, shape (n, objectives)) no other row dominates; non-finite rows never."""
    finite = np.all(np.isfinite(points), axis=1)
    keep = finite.copy()
    for i in np.flatnonzero(finite):
        others = points[finite]
        dominated = np.any(np.all(others <= points[i], axis=1) & np.any(others < points[i], axis=1))
        keep[i] = not dominated
    result: NDArray[np.bool_] = keep
    return result


@dataclass(frozen=True)
class ConstraintResult:
    """A constraint on one gain set.

    Attributes:
        constraint: The constraint.
        bound: Its numeric bound.
        value: The gain set's statistic of the column.
        passed: Whether the value meets the bound.
        miss: How far it misses, relative to the bound (0 when passed).
    """

    constraint: Constraint
    bound: float
    value: float
    passed: bool
    miss: float


@dataclass(frozen=True)
class SweepResult:
    """The analysed sweep.

    Attributes:
        columns: Index columns ``scenario.index``.
        statistics: ``{statistic: (gain sets, columns)}`` for p50, p95, worst.
        completed: Runs finished per gain set.
        pareto: Gain sets on the front.
        bounds: Constraint bounds from reference laws, by constraint text.
        constraint_results: Per gain set, each constraint's result.
        chosen: Chosen gain set, or None when no set has every index finite.
        chosen_meets_all: Whether the chosen set meets every constraint.
    """

    columns: tuple[str, ...]
    statistics: Mapping[str, FloatArray]
    completed: NDArray[np.int64]
    pareto: NDArray[np.bool_]
    bounds: Mapping[str, float]
    constraint_results: tuple[tuple[ConstraintResult, ...], ...]
    chosen: int | None
    chosen_meets_all: bool

    def value(self, statistic: str, gain_set: int, column: str) -> float:
        """One statistic of one column of one gain set."""
        return float(self.statistics[statistic][gain_set, self.columns.index(column)])


def _grid(spec: SweepSpec, table: pa.Table) -> tuple[FloatArray, NDArray[np.int64]]:
    """(gain sets, plant draws, columns) of index values (NaN where missing or diverged), runs per set."""
    sets, draws, scenarios = len(spec.gain_sets), len(spec.plant_draws), len(spec.scenarios)
    values = np.full((sets, draws, scenarios, len(INDEX_NAMES)), np.nan)
    present = np.zeros((sets, draws, scenarios), dtype=bool)
    run_ids = np.asarray(table.column("run_id").to_numpy(), dtype=np.int64)
    indices = (
        np.stack([table.column(name).to_numpy() for name in INDEX_NAMES], axis=-1)
        if len(table)
        else np.zeros((0, len(INDEX_NAMES)))
    )
    scenario = run_ids % scenarios
    rest = run_ids // scenarios
    gain_set, draw = rest // draws, rest % draws
    values[gain_set, draw, scenario] = indices
    present[gain_set, draw, scenario] = True
    completed = present.reshape(sets, -1).sum(axis=1)
    return values.reshape(sets, draws, scenarios * len(INDEX_NAMES)), completed


def _statistics(values: FloatArray) -> dict[str, FloatArray]:
    """P50, P95 and worst over the draws (axis 1); a diverged run (NaN) counts as +inf."""
    worst_case = np.where(np.isnan(values), np.inf, values)
    with np.errstate(invalid="ignore"):  # inf - inf between two diverged draws: the percentile is inf
        result = {
            name: np.percentile(worst_case, q, axis=1, method="linear") for name, q in _STATISTICS.items()
        }
    result = {name: np.where(np.isnan(stat), np.inf, stat) for name, stat in result.items()}
    result["worst"] = worst_case.max(axis=1)
    # An index that is NaN for every draw (a step metric of a sine) stays NaN.
    undefined = np.all(np.isnan(values), axis=1)
    return {name: np.where(undefined, np.nan, stat) for name, stat in result.items()}


def reference_bounds(spec: SweepSpec) -> dict[str, float]:
    """Each constraint's bound: fixed, or the best paper-gain run of its reference laws (base plant)."""
    bounds: dict[str, float] = {}
    cache: dict[tuple[str, str], dict[str, float]] = {}
    for constraint in spec.constraints:
        if constraint.value is not None:
            bounds[constraint.text()] = constraint.value
            continue
        scenario_name, _, index = constraint.column.partition(".")
        scenario = next(s for s in spec.scenarios if s.name == scenario_name)
        values = []
        for controller in constraint.controllers:
            key = (controller, scenario_name)
            if key not in cache:
                settings = RunSettings(
                    scenario=scenario,
                    controller=controller,
                    law=law_table()[controller].config(),
                    plant=scenario_plant_config(scenario),
                    td=TrackingDifferentiatorConfig(),
                    fleso=FLESOConfig(),
                    model=SMMParameters(),
                    output=OutputLimitConfig(),
                )
                cache[key] = run_batch([settings])[0]
            values.append(cache[key][index])
        best = min(values) if constraint.op in ("<", "<=") else max(values)
        bounds[constraint.text()] = constraint.factor * best
    return bounds


def _check(constraint: Constraint, bound: float, value: float) -> ConstraintResult:
    op = constraint.op
    passed = bool(
        math.isfinite(value)
        and (
            (op == "<" and value < bound)
            or (op == "<=" and value <= bound)
            or (op == ">" and value > bound)
            or (op == ">=" and value >= bound)
        )
    )
    if passed:
        miss = 0.0
    elif not math.isfinite(value):
        miss = math.inf
    else:
        miss = abs(value - bound) / max(abs(bound), 1e-300)
    return ConstraintResult(constraint, bound, value, passed, miss)


def analyse(spec: SweepSpec, table: pa.Table, bounds: Mapping[str, float] | None = None) -> SweepResult:
    """Statistics, front and choice of a sweep's runs (``table``: run_id and indices)."""
    columns = spec.columns()
    values, completed = _grid(spec, table)
    statistics = _statistics(values)
    chosen_stat = statistics[spec.statistic]
    objective_columns = [columns.index(c) for c in spec.objectives]
    pareto = pareto_mask(chosen_stat[:, objective_columns])
    if bounds is None:
        bounds = reference_bounds(spec)
    results = tuple(
        tuple(
            _check(c, bounds[c.text()], float(chosen_stat[g, columns.index(c.column)]))
            for c in spec.constraints
        )
        for g in range(len(spec.gain_sets))
    )
    select = chosen_stat[:, columns.index(spec.select)]
    meets = np.array([all(r.passed for r in rs) for rs in results], dtype=bool)
    candidates = np.flatnonzero(meets & np.isfinite(select))
    chosen: int | None
    if candidates.size:
        chosen = int(candidates[np.argmin(select[candidates])])
    else:
        misses = np.array([sum(r.miss for r in rs) for rs in results])
        order = np.lexsort((np.where(np.isfinite(select), select, np.inf), misses))
        finite = [int(i) for i in order if math.isfinite(misses[i]) and math.isfinite(select[i])]
        chosen = finite[0] if finite else None
    return SweepResult(
        columns=columns,
        statistics=statistics,
        completed=completed,
        pareto=pareto,
        bounds=dict(bounds),
        constraint_results=results,
        chosen=chosen,
        chosen_meets_all=bool(chosen is not None and meets[chosen]),
    )


def gain_set_table(spec: SweepSpec, result: SweepResult) -> pa.Table:
    """One row per gain set: its values, runs completed, front membership and every statistic."""
    columns: dict[str, list[object]] = {"gain_set": list(range(len(spec.gain_sets)))}
    for g, values in enumerate(spec.gain_sets):
        for name, value in _flat("gain.", values).items():
            columns.setdefault(name, [None] * len(spec.gain_sets))[g] = value
    columns["completed"] = result.completed.tolist()
    columns["pareto"] = result.pareto.tolist()
    columns["meets_constraints"] = [all(r.passed for r in rs) for rs in result.constraint_results]
    for statistic, array in result.statistics.items():
        for j, column in enumerate(result.columns):
            columns[f"{column}.{statistic}"] = array[:, j].tolist()
    return pa.table(columns)


def numeric_gains(spec: SweepSpec) -> list[tuple[str, Sequence[float]]]:
    """Each varied gain (joints as separate entries) with its value per gain set, numbers only."""
    result: list[tuple[str, Sequence[float]]] = []
    for name in spec.varied:
        values = [spec.gain_sets[g][name] for g in range(len(spec.gain_sets))]
        first = values[0]
        if isinstance(first, (list, tuple)):
            for joint in range(len(first)):
                result.append((f"{name}[{joint}]", [float(v[joint]) for v in values]))
        elif isinstance(first, (int, float)) and not isinstance(first, bool):
            result.append((name, [float(v) for v in values]))
    return result
