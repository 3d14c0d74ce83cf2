"""Markdown report of ``smm-bag analyze``: the bags, the side-by-side indices, the figures."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from smm_analysis.runs.indices import RunMetrics, comparison_table

__all__ = ["render_report"]


def render_report(results: Sequence[RunMetrics], plots: Mapping[str, str], out: Path) -> str:
    """The report text; figure links are relative to ``out``."""
    lines = ["# Recorded runs", ""]
    lines.append(
        "| bag | controller | scenario | seed | plant | steps (left out) | position used | version |"
    )
    lines.append("|---|---|---|---|---|---|---|---|")
    for result in results:
        run, manifest = result.run, result.run.manifest
        lines.append(
            f"| `{run.bag}` | {run.label} | {manifest.scenario or '-'} | "
            f"{'-' if manifest.seed is None else manifest.seed} | {manifest.plant or '-'} | "
            f"{run.steps} ({run.incomplete_steps}) | {run.position_source} | {manifest.version or '-'} |"
        )
    lines += [
        "",
        "## Indices (SPEC section 5)",
        "",
        "Ma, Ave, RMS of the tracking error q_d - q per joint (q = ground truth where the bag has it, "
        "else the measured position, as the column header says); eps_u = integral of the commanded "
        "torque squared; "
        "end-effector errors in mm.",
        "",
        comparison_table(results),
        "",
        "## Figures",
        "",
    ]
    for name, target in plots.items():
        path = Path(target)
        if path.suffix == ".png":
            relative = path.relative_to(out) if path.is_relative_to(out) else path
            lines.append(f"![{name}]({relative})")
        else:
            lines.append(f"* {name}: {target}")
    return "\n".join(lines) + "\n"
