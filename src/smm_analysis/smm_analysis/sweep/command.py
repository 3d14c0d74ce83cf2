"""The ``smm-sweep`` commands: run a sweep (and write its outputs), or re-run one run with the scalar loop.

Each returns an exit code: 0 success; 1 a re-run disagrees with the sweep beyond the tolerance of
``smm_analysis.batch``; 2 bad input (spec, folder, scheduler), with a message naming the field or address.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from smm_analysis.batch.loop import INDEX_NAMES, agreement_tolerance, scalar_indices
from smm_analysis.errors import AnalysisError
from smm_analysis.parameters_file import write_parameters_file
from smm_analysis.sweep.execute import prepare_folder, read_parts, run_sweep
from smm_analysis.sweep.outputs import parameters_sections, write_outputs
from smm_analysis.sweep.results import analyse
from smm_analysis.sweep.spec import load_spec

__all__ = ["EXIT_DISAGREES", "EXIT_ERROR", "EXIT_OK", "SweepOptions", "rerun", "sweep"]

EXIT_OK = 0
EXIT_DISAGREES = 1
EXIT_ERROR = 2


@dataclass(frozen=True)
class SweepOptions:
    """Parsed options of ``smm-sweep``.

    Attributes:
        spec: The spec file.
        out: Output folder (None: ``out/sweeps/<spec name>``).
        workers: Local processes.
        scheduler: Dask scheduler address, or None to run locally.
        rerun: Run id to re-run with the scalar loop, or None.
    """

    spec: Path
    out: Path | None
    workers: int
    scheduler: str | None
    rerun: int | None


class _Bar:
    """A one-line progress bar on a stream."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream

    def __call__(self, done: int, total: int) -> None:
        width = 30
        filled = width * done // max(total, 1)
        end = "\n" if done >= total else ""
        self.stream.write(f"\r[{'#' * filled}{'-' * (width - filled)}] {done}/{total} batches{end}")
        self.stream.flush()


def _out(options: SweepOptions, name: str) -> Path:
    return options.out if options.out is not None else Path("out") / "sweeps" / name


def sweep(options: SweepOptions, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """Runs (or resumes) the sweep of ``options.spec`` and writes its outputs; returns the exit code."""
    out_stream = stdout if stdout is not None else sys.stdout
    err_stream = stderr if stderr is not None else sys.stderr
    try:
        spec = load_spec(options.spec)
        out = _out(options, spec.name)
        where = (
            f"Dask scheduler {options.scheduler}"
            if options.scheduler
            else f"{options.workers} local process(es)"
        )
        out_stream.write(f"smm-sweep {spec.name}: {spec.run_count} runs on {where} -> {out}\n")
        ran = run_sweep(
            spec, out, workers=options.workers, scheduler=options.scheduler, progress=_Bar(err_stream)
        )
        indices = read_parts(out)
        result = analyse(spec, indices)
        files = write_outputs(spec, result, indices, out)
    except AnalysisError as error:
        err_stream.write(f"smm-sweep: error: {error}\n")
        return EXIT_ERROR
    out_stream.write(f"ran {ran} batches; wrote {', '.join(files)} in {out}\n")
    if result.chosen is not None:
        verdict = "meets every constraint" if result.chosen_meets_all else "closest; misses a constraint"
        out_stream.write(f"chosen gain set {result.chosen} ({verdict}): {out / 'chosen.yaml'}\n")
    return EXIT_OK


def rerun(options: SweepOptions, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """Re-runs one run of a finished sweep with the scalar loop and compares; returns the exit code."""
    out_stream = stdout if stdout is not None else sys.stdout
    err_stream = stderr if stderr is not None else sys.stderr
    assert options.rerun is not None
    try:
        spec = load_spec(options.spec)
        out = _out(options, spec.name)
        prepare_folder(spec, out)
        settings = spec.settings(options.rerun)
        table = read_parts(out)
        ids = table.column("run_id").to_pylist()
        if options.rerun not in ids:
            raise AnalysisError(f"run {options.rerun} has not finished in {out}; run the sweep first")
        row = ids.index(options.rerun)
        stored = {name: float(table.column(name)[row].as_py()) for name in INDEX_NAMES}
        scalar = scalar_indices(settings)
        path = write_parameters_file(
            out / f"rerun-{options.rerun}.yaml",
            parameters_sections(settings),
            comment=(
                f"smm-sweep {spec.name}: run {options.rerun} "
                f"(scenario {settings.scenario.name}, seed {settings.plant.seed})"
            ),
        )
    except AnalysisError as error:
        err_stream.write(f"smm-sweep: error: {error}\n")
        return EXIT_ERROR
    tolerance = agreement_tolerance(settings)
    agree = True
    out_stream.write(f"run {options.rerun}: scalar loop vs sweep (relative tolerance {tolerance:g})\n")
    for name in INDEX_NAMES:
        a, b = scalar[name], stored[name]
        same = (math.isnan(a) and math.isnan(b)) or (
            math.isfinite(a) and math.isfinite(b) and abs(a - b) <= tolerance * abs(a) + 1e-12
        )
        agree &= same
        out_stream.write(f"  {name:22s} {a:.10g}  {b:.10g}  {'ok' if same else 'DIFFERS'}\n")
    out_stream.write(f"parameters: {path}\n")
    return EXIT_OK if agree else EXIT_DISAGREES
