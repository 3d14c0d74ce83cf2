"""Figures of an identification: measured vs predicted torque, residuals, the excitation (PNG, Agg)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt

from smm_analysis.closed_loop import Trajectory
from smm_analysis.identification.data import PreparedRun
from smm_analysis.identification.estimate import RunFit
from smm_analysis.lumped import LumpedDisturbance

__all__ = ["lumped_figure", "write_identification_plots"]

_JOINTS = ("alpha", "beta")


def _slug(index: int, role: str) -> str:
    return f"{role}{index + 1}"


def _torque_figure(fit: RunFit, path: Path, title: str) -> Path:
    figure, axes = plt.subplots(2, 2, figsize=(11, 6), sharex=True, squeeze=False)
    for joint, name in enumerate(_JOINTS):
        used = fit.use[:, joint]
        top, bottom = axes[0, joint], axes[1, joint]
        top.plot(fit.time, fit.measured[:, joint], lw=0.8, label="measured (filtered)")
        top.plot(fit.time, fit.predicted[:, joint], lw=0.8, ls="--", label="model")
        top.set_title(f"{name}: NRMSE {fit.nrmse[joint]:.3g}")
        top.set_ylabel("torque (N m)")
        residual = fit.measured[:, joint] - fit.predicted[:, joint]
        bottom.plot(fit.time[used], residual[used], ".", ms=1, label="used")
        bottom.plot(fit.time[~used], residual[~used], ".", ms=1, color="0.7", label="left out")
        bottom.set_ylabel("residual (N m)")
        bottom.set_xlabel("time (s)")
        top.legend(fontsize="small")
        bottom.legend(fontsize="small", markerscale=6)
    figure.suptitle(title)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return path


def _excitation_figure(run: PreparedRun, path: Path) -> Path:
    figure, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    for joint, name in enumerate(_JOINTS):
        axes[0].plot(run.raw_time, run.raw_position[:, joint], lw=0.8, label=name)
        axes[1].plot(run.raw_time, run.raw_torque[:, joint], lw=0.6, label=name)
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


def write_identification_plots(
    runs: list[PreparedRun], fits: list[RunFit], validation: list[tuple[PreparedRun, RunFit]], directory: Path
) -> list[Path]:
    """Writes torque_<run>.png and excitation_<run>.png for identification and validation runs."""
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for index, (run, fit) in enumerate(zip(runs, fits, strict=True)):
        slug = _slug(index, "identification")
        written.append(
            _torque_figure(fit, directory / f"torque_{slug}.png", f"identification run {run.name}")
        )
        written.append(_excitation_figure(run, directory / f"excitation_{slug}.png"))
    for index, (run, fit) in enumerate(validation):
        slug = _slug(index, "validation")
        written.append(_torque_figure(fit, directory / f"torque_{slug}.png", f"validation run {run.name}"))
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
