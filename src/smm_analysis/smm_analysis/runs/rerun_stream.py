"""``smm-bag rerun`` in bounded memory: a survey pass over the steps, then the chain pass, block by block.

The survey finds what the whole run decides: whether every step has the effort (else the applied torque is
the previous recorded command) and a recorded estimate, and the largest recorded |values| the per-step
tolerance is relative to. The chain pass steps ``ChainStepper``, judges with ``AgreementAccumulator`` and
writes ``rerun.csv`` as it goes (docs/BAGS.md, "Streaming rerun").
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TextIO

import numpy as np
from numpy.typing import NDArray

from smm_analysis.runs.agreement import Agreement, AgreementAccumulator, Tolerance, allowed_difference
from smm_analysis.runs.rerun import ChainSettings, ChainStepper
from smm_analysis.runs.stream import StepStream

__all__ = ["RerunCsv", "RerunSummary", "RerunSurvey", "rerun_stream", "survey"]

FloatArray = NDArray[np.float64]
RowsSink = Callable[[NDArray[np.int64], FloatArray, FloatArray, FloatArray, FloatArray | None], None]
"""Called per block with stamps (ns), offline and recorded commands, offline and recorded estimates."""


@dataclass(frozen=True)
class RerunSurvey:
    """What the whole run decides, from a first pass.

    Attributes:
        steps: Steps in the run.
        effort_complete: Every step has the recorded effort (applied torque).
        estimate_complete: Every step has a recorded disturbance estimate.
        command_max: Largest recorded |command| per joint (N m), shape (2,).
        estimate_max: Largest recorded |estimate| per joint (N m), shape (2,) (0 where none).
    """

    steps: int
    effort_complete: bool
    estimate_complete: bool
    command_max: FloatArray
    estimate_max: FloatArray


def survey(stream: StepStream) -> RerunSurvey:
    """The survey of one pass over ``stream``'s steps.

    Raises:
        BagError: See :class:`~smm_analysis.runs.stream.StepStream`.
    """
    steps, effort, estimate = 0, True, True
    command_max, estimate_max = np.zeros(2), np.zeros(2)
    for block in stream.blocks():
        steps += block.t_ns.size
        effort = effort and bool(np.all(np.isfinite(block.applied_torque)))
        estimate = estimate and bool(np.all(np.isfinite(block.disturbance_estimate)))
        command_max = np.maximum(command_max, np.max(np.abs(block.command_torque), axis=0))
        if estimate:
            estimate_max = np.maximum(estimate_max, np.max(np.abs(block.disturbance_estimate), axis=0))
    return RerunSurvey(steps, effort, estimate, command_max, estimate_max)


@dataclass(frozen=True)
class RerunSummary:
    """What ``smm-bag rerun`` reports of one run.

    Attributes:
        steps: Steps re-run.
        applied_source: Where the applied torque came from.
        command_rms_offline: RMS over the steps of the offline command per joint (N m).
        command_rms_recorded: The same of the recorded command (N m).
        agreement: The verdict (largest differences, tolerances, flips, indices).
    """

    steps: int
    applied_source: str
    command_rms_offline: tuple[float, float]
    command_rms_recorded: tuple[float, float]
    agreement: Agreement


class _SquareSum:
    """Sum of squares per column in step order (numpy's order for ``mean(x**2, axis=0)`` of (N, 2))."""

    def __init__(self) -> None:
        self.total = np.zeros((1, 2))

    def add(self, values: FloatArray) -> None:
        self.total = np.add.reduce(np.vstack([self.total, values**2]), axis=0, keepdims=True)

    def rms(self, steps: int) -> tuple[float, float]:
        root = np.sqrt(self.total[0] / steps)
        return float(root[0]), float(root[1])


def rerun_stream(
    stream: StepStream,
    settings: ChainSettings,
    found: RerunSurvey,
    tolerance: Tolerance,
    rows: RowsSink | None = None,
) -> RerunSummary:
    """Steps the chain over ``stream`` (a second reading of the surveyed steps) and judges it.

    Args:
        stream: The steps (the same bag and window as the survey's).
        settings: The chain to run.
        found: The survey of the same steps.
        tolerance: What the judgement allows.
        rows: Called with each block's rows (for ``rerun.csv``), or None.

    Raises:
        BagError: See :class:`~smm_analysis.runs.stream.StepStream`.
    """
    stepper = ChainStepper(
        settings, stream.manifest.control_period_ns / 1e9, from_effort=found.effort_complete
    )
    estimate_allowed = allowed_difference(found.estimate_max, tolerance) if found.estimate_complete else None
    accumulator = AgreementAccumulator(
        steps=found.steps,
        command_allowed=allowed_difference(found.command_max, tolerance),
        flip_size=settings.flip_size,
        tolerance=tolerance,
        estimate_allowed=estimate_allowed,
    )
    offline, recorded = _SquareSum(), _SquareSum()
    for block in stream.blocks():
        command, estimate = stepper.step(
            block.measured_position, block.applied_torque, block.command_torque, block.reference
        )
        recorded_estimate = block.disturbance_estimate if found.estimate_complete else None
        accumulator.add(block.t_ns, command, block.command_torque, estimate, recorded_estimate)
        offline.add(command)
        recorded.add(block.command_torque)
        if rows is not None:
            rows(block.t_ns, command, block.command_torque, estimate, recorded_estimate)
    agreement = accumulator.result()
    return RerunSummary(
        steps=accumulator.steps,
        applied_source=stepper.applied_source,
        command_rms_offline=offline.rms(accumulator.steps),
        command_rms_recorded=recorded.rms(accumulator.steps),
        agreement=agreement,
    )


class RerunCsv:
    """``rerun.csv`` written block by block (into ``<path>.partial``, renamed when closed without error).

    Args:
        path: The file.
        recorded_estimate: Whether the rows have the recorded estimate's columns.
    """

    def __init__(self, path: Path, *, recorded_estimate: bool) -> None:
        self.path = path
        self.partial = path.with_name(path.name + ".partial")
        names = ["command_offline", "command_recorded", "estimate_offline"]
        if recorded_estimate:
            names.append("estimate_recorded")
        self.header = ",".join(
            ["t_ns", *(f"{name}_{joint}" for name in names for joint in ("alpha", "beta"))]
        )
        self._file: TextIO | None = None

    def __enter__(self) -> RerunCsv:
        self._file = self.partial.open("w", encoding="utf-8")
        self._file.write(self.header + "\n")
        return self

    def __call__(
        self,
        t_ns: NDArray[np.int64],
        command: FloatArray,
        recorded_command: FloatArray,
        estimate: FloatArray,
        recorded_estimate: FloatArray | None,
    ) -> None:
        """Writes the rows of one block."""
        assert self._file is not None
        columns = [t_ns.astype(np.float64).reshape(-1, 1), command, recorded_command, estimate]
        if recorded_estimate is not None:
            columns.append(recorded_estimate)
        np.savetxt(self._file, np.hstack(columns), delimiter=",", fmt="%.17g")

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        assert self._file is not None
        self._file.close()
        if kind is None:
            os.replace(self.partial, self.path)
        else:
            self.partial.unlink(missing_ok=True)
