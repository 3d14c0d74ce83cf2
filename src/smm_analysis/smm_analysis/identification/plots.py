"""Figures of an identification, from envelopes of the runs: torque and model, residuals, the excitation."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt

from smm_analysis.closed_loop import Trajectory
from smm_analysis.lumped import LumpedDisturbance
from smm_analysis.runs.envelope import Envelope
from smm_analysis.runs.plots import drawing

__all__ = ["RunFigures", "lumped_figure", "write_identification_plots"]

_JOINTS = ("alpha", "beta")


@dataclass(frozen=True)
class RunFigures:
    """What the figures of one run show.

    Attributes:
        role: ``identification`` or ``validation``.
        name: The run.
        nrmse: Torque NRMSE per joint.
        fit: Envelope of ``measured``, ``model``, ``used`` and ``left out`` residual per joint (N m).
        excitation: Envelope of ``q`` (rad) and ``tau`` (N m) per joint.
    """

    role: str
    name: str
    nrmse: tuple[float, float]
    fit: Envelope
    excitation: Envelope


def _torque_figure(run: RunFigures, path: Path) -> Path:
    figure, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True, squeeze=False)
    for joint, name in enumerate(_JOINTS):
        top, bottom = axes[0, joint], axes[1, joint]
        top.plot(*run.fit.line(f"measured {name}"), lw=0.8, label="measured (filtered)")
        top.plot(*run.fit.line(f"model {name}"), lw=0.8, ls="--", label="model")
        top.set_title(f"{name}: NRMSE {run.nrmse[joint]:.3g}")
        top.set_ylabel("torque (N m)")
        bottom.plot(*run.fit.line(f"used {name}"), ".", ms=1, label="used")
        bottom.plot(*run.fit.line(f"left out {name}"), ".", ms=1, color="0.7", label="left out")
        bottom.set_ylabel("residual (N m)")
        bottom.set_xlabel("time (s)")
        top.legend(fontsize="small")
        bottom.legend(fontsize="small", markerscale=6)
    figure.suptitle(f"{run.role} run {run.name} (min/max per column of steps)")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def _excitation_figure(run: RunFigures, path: Path) -> Path:
    figure, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    for name in _JOINTS:
        axes[0].plot(*run.excitation.line(f"q {name}"), lw=0.8, label=name)
        axes[1].plot(*run.excitation.line(f"tau {name}"), lw=0.6, label=name)
    axes[0].set_ylabel("measured position (rad)")
    axes[1].set_ylabel("applied torque (N m)")
    axes[1].set_xlabel("time (s)")
    for axis in axes:
        axis.legend(fontsize="small")
    figure.suptitle(f"excitation: {run.name}")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def write_identification_plots(runs: Sequence[RunFigures], directory: Path) -> list[Path]:
    """Writes torque_<role><n>.png and excitation_<role><n>.png per run (n counts within a role, from 1)."""
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    numbers: dict[str, int] = {}
    with drawing():
        for run in runs:
            numbers[run.role] = numbers.get(run.role, 0) + 1
            slug = f"{run.role}{numbers[run.role]}"
            written.append(_torque_figure(run, directory / f"torque_{slug}.png"))
            written.append(_excitation_figure(run, directory / f"excitation_{slug}.png"))
    return written


def lumped_figure(runs: list[tuple[str, Trajectory, LumpedDisturbance]], path: Path) -> Path:
    """The FLESO's estimate beside the true lumped disturbance and its model-error part, one row per run."""
    figure, axes = plt.subplots(len(runs), 2, figsize=(11, 3.2 * len(runs)), sharex=True, squeeze=False)
    for row, (label, run, parts) in enumerate(runs):
        for joint, name in enumerate(_JOINTS):
            axis = axes[row, joint]
            axis.plot(run.time, parts.total[:, joint], lw=0.8, label="true lumped (model error + external)")
            axis.plot(run.time, run.disturbance_estimate[:, joint], lw=0.8, label="FLESO estimate")
            axis.plot(run.time, parts.model_error[:, joint], lw=0.8, ls=":", label="model-error part")
            axis.plot(run.time, parts.external[:, joint], lw=0.8, ls="--", label="external part (eq. 46)")
            axis.set_title(f"{label}: {name}")
            axis.set_ylabel("N m")
            axis.grid(True, alpha=0.3)
        axes[row, 0].legend(fontsize="x-small")
    for joint in (0, 1):
        axes[-1, joint].set_xlabel("time (s)")
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return path
