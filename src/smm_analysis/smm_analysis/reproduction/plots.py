"""PNG figures like the paper's Figs 12-17 and 19-20 (matplotlib, Agg backend, no display needed).

``step_<joint>.png`` (Figs 12-13, the retuned FPDESO set beside the paper's; the other figures show the
paper's gains only), ``case1_tracking_<joint>.png`` and ``case1_error_<joint>.png`` (Figs 14-17),
``case2_tracking_<joint>.png`` (Figs 19-20) and ``case2_disturbance_<joint>.png`` (FLESO estimate xi~
next to the eq. 46 disturbance; no figure of the paper).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
from matplotlib.figure import Figure
from smm_controller.laws import law_names

from smm_analysis.errors import AnalysisError
from smm_analysis.reproduction.results import JOINTS, ReproductionResult, RunResult
from smm_analysis.reproduction.retuned import RETUNED_SETS, controller_label

__all__ = ["DEFAULT_DPI", "write_plots"]

DEFAULT_DPI = 80
_FIGSIZE = (7.0, 3.4)
_PALETTE: tuple[dict[str, Any], ...] = (
    {"color": "tab:red", "linestyle": "-"},
    {"color": "tab:blue", "linestyle": "--"},
    {"color": "tab:green", "linestyle": "-."},
    {"color": "tab:purple", "linestyle": ":"},
    {"color": "tab:brown", "linestyle": (0, (3, 1, 1, 1))},
    {"color": "tab:pink", "linestyle": (0, (1, 2))},
    {"color": "tab:gray", "linestyle": (0, (5, 3))},
)
"""Line styles given to the laws in the table's order (the paper's four first), cycled past the seventh."""
_RETUNED_STYLE: dict[str, Any] = {"color": "tab:orange", "linestyle": (0, (6, 2))}


def _style(name: str) -> dict[str, Any]:
    if name in RETUNED_SETS:
        return _RETUNED_STYLE
    names = law_names()
    return _PALETTE[names.index(name) % len(_PALETTE)] if name in names else {}


_SYMBOLS = {"alpha": "\u03b1", "beta": "\u03b2"}


def _runs(result: ReproductionResult, scenario: str, *, retuned: bool = False) -> list[RunResult]:
    return [
        run
        for name in result.controllers
        if (retuned or name not in RETUNED_SETS) and (run := result.run(scenario, name)) is not None
    ]


def _legend_label(name: str) -> str:
    return "FPDESO (paper gains)" if name == "fpdeso" else controller_label(name)


def _save(figure: Figure, path: Path, dpi: int) -> Path:
    figure.tight_layout()
    figure.savefig(path, dpi=dpi)
    plt.close(figure)
    return path


def _tracking_figure(runs: Sequence[RunResult], joint: int, title: str, error: bool) -> Figure:
    figure, axes = plt.subplots(figsize=_FIGSIZE)
    first = runs[0].trajectory
    if not error:
        axes.plot(
            first.time, first.desired_position[:, joint], color="black", linewidth=1.0, label="reference"
        )
    for run in runs:
        trajectory = run.trajectory
        values = trajectory.tracking_error[:, joint] if error else trajectory.position[:, joint]
        axes.plot(
            trajectory.time,
            values,
            linewidth=1.0,
            label=_legend_label(run.controller),
            **_style(run.controller),
        )
    axes.set_xlabel("t (s)")
    axes.set_ylabel(f"{'error ' if error else ''}{_SYMBOLS[JOINTS[joint]]} (rad)")
    axes.set_title(title, fontsize=10)
    axes.grid(True, linewidth=0.3)
    axes.legend(fontsize=8, loc="best")
    return figure


def write_plots(result: ReproductionResult, directory: Path, *, dpi: int = DEFAULT_DPI) -> list[Path]:
    """Writes every figure whose runs are present into ``directory``.

    Args:
        result: The reproduction results (with trajectories).
        directory: Output folder (created if missing).
        dpi: Resolution (dots per inch); 80 keeps each PNG around 30-50 kB.

    Returns:
        The files written, in a stable order.

    Raises:
        AnalysisError: The folder cannot be created or written.
    """
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise AnalysisError(f"cannot create plot folder {directory}: {error}") from error
    written: list[Path] = []
    try:
        step = _runs(result, "step", retuned=True)
        case1 = _runs(result, "case1")
        case2 = _runs(result, "case2")
        for index, joint in enumerate(JOINTS):
            symbol = _SYMBOLS[joint]
            if step:
                written.append(
                    _save(
                        _tracking_figure(
                            step, index, f"Step response, {symbol} (paper Fig. {12 + index})", False
                        ),
                        directory / f"step_{joint}.png",
                        dpi,
                    )
                )
            if case1:
                written.append(
                    _save(
                        _tracking_figure(
                            case1, index, f"Case 1 tracking, {symbol} (paper Fig. {14 + 2 * index})", False
                        ),
                        directory / f"case1_tracking_{joint}.png",
                        dpi,
                    )
                )
                written.append(
                    _save(
                        _tracking_figure(
                            case1,
                            index,
                            f"Case 1 tracking error, {symbol} (paper Fig. {15 + 2 * index})",
                            True,
                        ),
                        directory / f"case1_error_{joint}.png",
                        dpi,
                    )
                )
            if case2:
                written.append(
                    _save(
                        _tracking_figure(
                            case2, index, f"Case 2 tracking, {symbol} (paper Fig. {19 + index})", False
                        ),
                        directory / f"case2_tracking_{joint}.png",
                        dpi,
                    )
                )
                written.append(
                    _save(
                        _tracking_figure(case2, index, f"Case 2 tracking error, {symbol}", True),
                        directory / f"case2_error_{joint}.png",
                        dpi,
                    )
                )
        fpdeso2 = result.run("case2", "fpdeso")
        if fpdeso2 is not None:
            trajectory = fpdeso2.trajectory
            figure, axes = plt.subplots(figsize=_FIGSIZE)
            for index, joint in enumerate(JOINTS):
                color = "tab:red" if index == 0 else "tab:blue"
                axes.plot(
                    trajectory.time,
                    trajectory.disturbance_estimate[:, index],
                    color=color,
                    linewidth=0.8,
                    label=f"FLESO estimate, {_SYMBOLS[joint]}",
                )
                axes.plot(
                    trajectory.time,
                    trajectory.disturbance_torque[:, index],
                    color=color,
                    linewidth=1.2,
                    linestyle="--",
                    label=f"eq. 46 disturbance, {_SYMBOLS[joint]}",
                )
            axes.set_xlabel("t (s)")
            axes.set_ylabel("torque (N m)")
            axes.set_title(
                "Case 2: FLESO total-disturbance estimate (includes the +10 % inertia error)", fontsize=10
            )
            axes.grid(True, linewidth=0.3)
            axes.legend(fontsize=7, loc="lower left", ncol=2)
            written.append(_save(figure, directory / "case2_disturbance.png", dpi))
    except OSError as error:
        raise AnalysisError(f"cannot write plots into {directory}: {error}") from error
    return written
