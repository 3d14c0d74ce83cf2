"""PNG figures of recorded runs, several bags overlaid, each line thinned to at most 5000 points.

Tracking, error, torque, estimated vs true disturbance, observer bandwidth, fuzzy gains (one panel per
joint); the loop latency's distribution (one panel, p50 and p99 marked).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray
from smm_sim.plant import disturbance_torque

from smm_analysis.runs.latency import latency_cdf, summarize_latency
from smm_analysis.runs.recorded import JOINTS, RecordedRun
from smm_analysis.scenarios import get_scenario

__all__ = ["PLOTS", "true_disturbance", "write_plots"]

FloatArray = NDArray[np.float64]
_MAX_POINTS = 5000
_DPI = 80

PLOTS = ("tracking", "error", "torque", "disturbance", "bandwidth", "fuzzy_gains", "latency")
"""Figure names (``<name>.png``)."""


def true_disturbance(run: RecordedRun) -> FloatArray | None:
    """The scenario's disturbance model at the recorded steps (N m), shape (N, 2); None if unknown.

    Simulator runs only: the manifest names the scenario, whose model gives the torque the plant applied.
    """
    if run.manifest.plant != "sim" or not run.manifest.scenario:
        return None
    try:
        model = get_scenario(run.manifest.scenario).disturbance
    except ValueError:  # a scenario this version does not know
        return None
    return np.array([disturbance_torque(model, float(t)) for t in run.time_s])


def _thin(run: RecordedRun) -> slice:
    return slice(None, None, max(1, run.t_ns.size // _MAX_POINTS))


def _figure(
    runs: Sequence[RecordedRun],
    title: str,
    unit: str,
    series: Callable[[RecordedRun, int], list[tuple[str, FloatArray, str]]],
) -> Figure | None:
    figure, axes = plt.subplots(1, 2, figsize=(10.0, 3.6), sharex=True)
    drawn = False
    for index, joint in enumerate(JOINTS):
        axis = axes[index]
        for run in runs:
            keep = _thin(run)
            for label, values, style in series(run, index):
                axis.plot(run.time_s[keep], values[keep], style, label=label, linewidth=0.9)
                drawn = True
        axis.set_title(f"{title}: {joint}")
        axis.set_xlabel("t (s)")
        axis.set_ylabel(unit)
        axis.grid(True, alpha=0.3)
        if axis.lines:
            axis.legend(fontsize=7)
    figure.tight_layout()
    if not drawn:
        plt.close(figure)
        return None
    return figure


def _latency_figure(runs: Sequence[RecordedRun]) -> Figure | None:
    """Empirical CDF of each run's loop latency, p50 dashed and p99 dotted; the axis ends at twice the p99."""
    timed = [run for run in runs if run.latency_ns is not None]
    if not timed:
        return None
    figure, axis = plt.subplots(figsize=(10.0, 3.6))
    left, right = 0.0, 0.0
    for run in timed:
        assert run.latency_ns is not None
        values, fraction = latency_cdf(run.latency_ns)
        summary = summarize_latency(run.latency_ns)
        (line,) = axis.step(values, fraction, where="post", linewidth=0.9, label=run.label)
        for value, style, name in ((summary.p50_ms, "--", "p50"), (summary.p99_ms, ":", "p99")):
            axis.axvline(
                value,
                color=line.get_color(),
                linestyle=style,
                linewidth=0.8,
                label=f"{run.label} {name} {value:.3g} ms",
            )
        axis.plot([], [], " ", label=f"{run.label} max {summary.max_ms:.3g} ms")
        left, right = min(left, float(values[0])), max(right, 2.0 * summary.p99_ms)
    if right > left:
        axis.set_xlim(left, right)
    axis.set_title("loop latency: command receive time - measurement receive time")
    axis.set_xlabel("latency (ms)")
    axis.set_ylabel("fraction of steps at or below")
    axis.set_ylim(0.0, 1.0)
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize=7, loc="lower right")
    figure.tight_layout()
    return figure


def _internal(run: RecordedRun, suffix: str) -> list[tuple[str, FloatArray]]:
    return [(key, values) for key, values in sorted(run.internals.items()) if key.endswith(suffix)]


def write_plots(runs: Sequence[RecordedRun], out: Path) -> dict[str, str]:
    """Writes the figures into ``out``; returns ``{name: file or reason it was not drawn}``."""
    out.mkdir(parents=True, exist_ok=True)
    truths = {id(run): true_disturbance(run) for run in runs}

    def tracking(run: RecordedRun, j: int) -> list[tuple[str, FloatArray, str]]:
        return [
            (f"{run.label} q_d", run.desired_position[:, j], "--"),
            (f"{run.label} q ({run.position_source})", run.position[:, j], "-"),
        ]

    def error(run: RecordedRun, j: int) -> list[tuple[str, FloatArray, str]]:
        return [(run.label, run.desired_position[:, j] - run.position[:, j], "-")]

    def torque(run: RecordedRun, j: int) -> list[tuple[str, FloatArray, str]]:
        lines = [(f"{run.label} command", run.command_torque[:, j], "-")]
        if run.applied_torque is not None:
            lines.append((f"{run.label} applied (prev. interval)", run.applied_torque[:, j], ":"))
        return lines

    def disturbance(run: RecordedRun, j: int) -> list[tuple[str, FloatArray, str]]:
        lines = []
        if run.disturbance_estimate is not None:
            lines.append((f"{run.label} estimate xi~", run.disturbance_estimate[:, j], "-"))
        truth = truths[id(run)]
        if truth is not None:
            lines.append((f"{run.label} true (scenario {run.manifest.scenario})", truth[:, j], "--"))
        return lines

    def bandwidth(run: RecordedRun, j: int) -> list[tuple[str, FloatArray, str]]:
        return [(f"{run.label} {key}", values[:, j], "-") for key, values in _internal(run, "bandwidth")]

    def gains(run: RecordedRun, j: int) -> list[tuple[str, FloatArray, str]]:
        chosen = _internal(run, ".kp") + _internal(run, ".kd")
        return [(f"{run.label} {key}", values[:, j], "-") for key, values in chosen]

    specs: dict[str, tuple[str, str, Callable[[RecordedRun, int], list[tuple[str, FloatArray, str]]]]] = {
        "tracking": ("tracking", "rad", tracking),
        "error": ("tracking error q_d - q", "rad", error),
        "torque": ("torque", "N m", torque),
        "disturbance": ("disturbance", "N m", disturbance),
        "bandwidth": ("observer bandwidth", "rad/s", bandwidth),
        "fuzzy_gains": ("fuzzy gains", "gain", gains),
    }
    figures = {name: _figure(runs, title, unit, series) for name, (title, unit, series) in specs.items()}
    figures["latency"] = _latency_figure(runs)
    written: dict[str, str] = {}
    for name, figure in figures.items():
        if figure is None:
            written[name] = "not recorded in these bags"
            continue
        path = out / f"{name}.png"
        figure.savefig(path, dpi=_DPI)
        plt.close(figure)
        written[name] = str(path)
    return written
