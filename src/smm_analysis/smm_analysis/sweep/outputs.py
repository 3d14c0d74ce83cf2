"""The files a sweep writes: runs and gain sets as Parquet, plots, the Markdown report, the chosen gains.

``runs.parquet`` (every run's settings and indices), ``gain_sets.parquet`` (statistics per gain set),
``pareto.png``, ``sensitivity.png``, ``report.md`` and ``chosen.yaml``, a ROS parameters file with the
chosen gain set that ``smm-launch --params-file`` takes as it is.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from smm_controller.laws import get_law
from smm_schema.fields import config_to_parameters

from smm_analysis.batch.loop import RunSettings
from smm_analysis.parameters_file import write_parameters_file
from smm_analysis.sweep.results import SweepResult, gain_set_table, numeric_gains, runs_table
from smm_analysis.sweep.spec import SweepSpec

__all__ = ["parameters_sections", "write_outputs"]


def parameters_sections(settings: RunSettings) -> dict[str, dict[str, Any]]:
    """``{node key: {parameter: value}}`` of a run's controller side (law, TD, FLESO, model, output limits).

    Non-finite values (``inf`` = no limit, a node default) are left out: a parameters file cannot hold them.
    """
    controller: dict[str, Any] = {"algorithm": settings.controller}
    controller.update(config_to_parameters(settings.law, settings.controller))
    controller.update(config_to_parameters(settings.output, "output"))
    chain: dict[str, Any] = {}
    chain.update(config_to_parameters(settings.td, "td"))
    if get_law(settings.controller).uses_disturbance_estimate:
        chain.update(config_to_parameters(settings.fleso, "fleso"))
    chain.update(config_to_parameters(settings.model, "model"))

    def finite(values: Mapping[str, Any]) -> dict[str, Any]:
        def ok(value: Any) -> bool:
            items = value if isinstance(value, list) else [value]
            return all(not isinstance(v, float) or math.isfinite(v) for v in items)

        return {name: value for name, value in values.items() if ok(value)}

    return {"/**/controller_node": finite(controller), "/**": finite(chain)}


def _plots(spec: SweepSpec, result: SweepResult, out: Path) -> list[str]:
    stat = result.statistics[spec.statistic]
    columns = result.columns
    objectives = list(spec.objectives)
    written = []
    x_name = objectives[0]
    others = objectives[1:] or objectives[:1]
    figure, axes = plt.subplots(1, len(others), figsize=(5 * len(others), 4), squeeze=False)
    x = stat[:, columns.index(x_name)]
    for axis, y_name in zip(axes[0], others, strict=True):
        y = stat[:, columns.index(y_name)]
        axis.scatter(x, y, s=10, color="0.6", label="gain sets")
        front = result.pareto
        order = np.argsort(x[front])
        # A front of two objectives is a line; of more, its points seen in this plane are not.
        style = "o-" if len(objectives) == 2 else "o"
        axis.plot(x[front][order], y[front][order], style, color="C3", markersize=4, label="Pareto front")
        if result.chosen is not None:
            axis.plot(x[result.chosen], y[result.chosen], "*", markersize=14, color="C2", label="chosen")
        axis.set_xlabel(f"{x_name} ({spec.statistic})")
        axis.set_ylabel(f"{y_name} ({spec.statistic})")
        axis.legend(fontsize=7)
    figure.suptitle(f"{spec.name}: Pareto front")
    figure.tight_layout()
    figure.savefig(out / "pareto.png", dpi=110)
    plt.close(figure)
    written.append("pareto.png")
    gains = numeric_gains(spec)
    if gains:
        figure, axes = plt.subplots(
            len(objectives), len(gains), figsize=(3.2 * len(gains), 2.6 * len(objectives)), squeeze=False
        )
        for row, objective in enumerate(objectives):
            y = stat[:, columns.index(objective)]
            for col, (name, values) in enumerate(gains):
                axis = axes[row][col]
                axis.scatter(values, y, s=6)
                if row == len(objectives) - 1:
                    axis.set_xlabel(name, fontsize=8)
                if col == 0:
                    axis.set_ylabel(objective, fontsize=8)
        figure.suptitle(f"{spec.name}: sensitivity of each objective ({spec.statistic}) to each gain")
        figure.tight_layout()
        figure.savefig(out / "sensitivity.png", dpi=100)
        plt.close(figure)
        written.append("sensitivity.png")
    return written


def _value(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return str(value)


def _report(spec: SweepSpec, result: SweepResult, table: pa.Table, files: list[str]) -> str:
    diverged = int(np.sum(np.isnan(table.column("RMS_alpha").to_numpy()))) if len(table) else 0
    lines = [
        f"# Sweep {spec.name}",
        "",
        f"Law {spec.controller}; scenarios {', '.join(s.name for s in spec.scenarios)}; "
        f"{len(spec.gain_sets)} gain sets x {len(spec.plant_draws)} plant draws x "
        f"{len(spec.scenarios)} scenarios = {spec.run_count} runs "
        f"({len(table)} finished, {diverged} diverged).",
        f"Objectives (minimised, {spec.statistic} over the plant draws): {', '.join(spec.objectives)}.",
        f"Varied: {', '.join(spec.varied) or 'nothing'}. "
        f"Fixed: {_value(spec.fixed) if spec.fixed else 'nothing'}.",
        "",
        "## Pareto front",
        "",
        "| gain set | " + " | ".join(spec.varied) + " | " + " | ".join(spec.objectives) + " |",
        "|---" * (1 + len(spec.varied) + len(spec.objectives)) + "|",
    ]
    for g in np.flatnonzero(result.pareto).tolist():
        gains = [_value(spec.gain_sets[g][name]) for name in spec.varied]
        values = [f"{result.value(spec.statistic, int(g), c):.4g}" for c in spec.objectives]
        lines.append(f"| {g} | " + " | ".join(gains) + " | " + " | ".join(values) + " |")
    if len(spec.plant_draws) > 1:
        lines += ["", "## Robustness over the plant draws (front and chosen set)", ""]
        lines.append("| gain set | objective | P50 | P95 | worst |")
        lines.append("|---|---|---|---|---|")
        shown = sorted(
            {*np.flatnonzero(result.pareto).tolist(), *([result.chosen] if result.chosen is not None else [])}
        )
        for g in shown:
            for c in spec.objectives:
                stats = [f"{result.value(s, g, c):.4g}" for s in ("p50", "p95", "worst")]
                lines.append(f"| {g} | {c} | " + " | ".join(stats) + " |")
    lines += ["", "## Chosen gain set", ""]
    if result.chosen is None:
        lines.append("No gain set has finite indices.")
    else:
        g = result.chosen
        verdict = (
            "meets every constraint"
            if result.chosen_meets_all
            else "meets NOT every constraint: the closest set"
        )
        lines.append(f"Gain set {g} ({verdict}; least {spec.select} ({spec.statistic}) among those that do).")
        lines.append("")
        for name in spec.varied:
            lines.append(f"- `{name}` = {_value(spec.gain_sets[g][name])}")
        if spec.constraints:
            lines += ["", "| constraint | bound | value | met | miss |", "|---|---|---|---|---|"]
            for r in result.constraint_results[g]:
                miss = "" if r.passed else f"{100 * r.miss:.2f} %"
                lines.append(
                    f"| {r.constraint.text()} | {r.bound:.4g} | {r.value:.4g} | "
                    f"{'yes' if r.passed else 'NO'} | {miss} |"
                )
        lines += ["", "Its ROS parameters: `chosen.yaml` (`smm-launch --params-file chosen.yaml`)."]
    lines += ["", "Files: " + ", ".join(f"`{f}`" for f in files), ""]
    return "\n".join(lines)


def write_outputs(spec: SweepSpec, result: SweepResult, indices: pa.Table, out: Path) -> list[str]:
    """Writes every output file into ``out``; returns their names."""
    table = runs_table(spec, indices)
    pq.write_table(table, out / "runs.parquet")
    pq.write_table(gain_set_table(spec, result), out / "gain_sets.parquet")
    files = ["runs.parquet", "gain_sets.parquet", *_plots(spec, result, out)]
    if result.chosen is not None:
        run_id = result.chosen * len(spec.plant_draws) * len(spec.scenarios)
        write_parameters_file(
            out / "chosen.yaml",
            parameters_sections(spec.settings(run_id)),
            comment=f"smm-sweep {spec.name}: chosen gain set {result.chosen} (see report.md)",
        )
        files.append("chosen.yaml")
    files.append("report.md")
    (out / "report.md").write_text(_report(spec, result, table, files), encoding="utf-8")
    return files
