"""``smm-bag analyze`` and ``smm-bag rerun``: each takes its options, prints, and returns an exit code."""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np
from smm_bag.errors import BagError, MissingTopicsError
from smm_bag.exit_codes import EXIT_CHECK_FAILED, EXIT_CORRUPT, EXIT_OK, EXIT_PARAMS, EXIT_USAGE, fail
from smm_bag.progress import Progress

from smm_analysis.errors import ParamsFileError
from smm_analysis.runs.agreement import judge, tolerance_for
from smm_analysis.runs.indices import comparison_table, evaluate_stream, metrics_document
from smm_analysis.runs.plots import RunFigures, write_plots
from smm_analysis.runs.recorded import load_run
from smm_analysis.runs.report import render_report
from smm_analysis.runs.rerun import chain_settings, read_params_files, rerun
from smm_analysis.runs.segments import MIN_SEGMENT_NS, find_segments
from smm_analysis.runs.stream import StepStream
from smm_analysis.runs.window import TimeWindow

__all__ = ["AnalyzeOptions", "RerunOptions", "analyze", "rerun_command", "streams_of"]


@dataclass(frozen=True)
class AnalyzeOptions:
    """Options of ``smm-bag analyze``."""

    bags: Sequence[Path]
    json: bool = False
    out: Path | None = None
    plots: bool = True
    quiet: bool = False
    window: TimeWindow = field(default_factory=TimeWindow)
    segments: bool = False


def streams_of(
    bag: Path, *, window: TimeWindow, segments: bool, quiet: bool, err: TextIO
) -> list[tuple[StepStream, str | None]]:
    """The streams to read in ``bag``: the window, or each segment (with its label) for ``--segments``."""
    progress = Progress(f"reading {bag.name}", 1, err, enabled=not quiet)
    if not segments:
        return [(StepStream(bag, window=window, progress=progress), None)]
    search = find_segments(bag, progress=progress)
    if search.short_segments or search.disarmed_steps:
        err.write(
            f"{bag}: {len(search.segments)} segments; left out: {search.short_segments} shorter than "
            f"{MIN_SEGMENT_NS / 1e9:g} s, {search.disarmed_steps} disarmed steps\n"
        )
    if not search.segments:
        raise MissingTopicsError(f"{bag}: no segment of at least {MIN_SEGMENT_NS / 1e9:g} s")
    runs: list[tuple[StepStream, str | None]] = []
    for segment in search.segments:
        label = f"segment {segment.number}"
        progress = Progress(f"{label} of {bag.name}", 1, err, enabled=not quiet)
        stream = StepStream(bag, window=segment.window, progress=progress)
        runs.append((stream, f"{stream.label} {label} ({segment.reason})"))
    return runs


def analyze(options: AnalyzeOptions, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """``smm-bag analyze BAG [BAG...]``: indices (table or ``--json``), figures and report into ``--out``."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    results = []
    figures: list[RunFigures] = []
    drawing = options.out is not None and options.plots
    try:
        for bag in options.bags:
            streams = streams_of(
                bag, window=options.window, segments=options.segments, quiet=options.quiet, err=err
            )
            for stream, label in streams:
                consumers = []
                if drawing:
                    name = label if label is not None else stream.label
                    figures.append(RunFigures(name, stream.manifest, stream.position_source))
                    consumers.append(figures[-1].add)
                results.append(evaluate_stream(stream, consumers=consumers, label=label))
    except BagError as error:
        return fail(error, err)
    except ValueError as error:  # smm_analysis.MetricsInputError: recorded values the metrics refuse
        err.write(f"smm-bag: error: {error}\n")
        return EXIT_CORRUPT
    document = metrics_document(results)
    if options.json:
        out.write(json.dumps(document, indent=2, allow_nan=False) + "\n")
    else:
        out.write(comparison_table(results) + "\n")
        for result in results:
            if result.run.incomplete_steps:
                out.write(
                    f"note: {result.run.bag}: {result.run.incomplete_steps} steps lack a measurement, "
                    "reference or command and were left out\n"
                )
            for topic, count in sorted(result.run.late_messages.items()):
                out.write(
                    f"note: {result.run.bag}: {count} messages on {topic} came more than the reorder window "
                    "after a later stamp and were left out\n"
                )
    if options.out is not None:
        options.out.mkdir(parents=True, exist_ok=True)
        (options.out / "metrics.json").write_text(json.dumps(document, indent=2, allow_nan=False) + "\n")
        plots = write_plots(figures, options.out) if drawing else {}
        report = options.out / "REPORT.md"
        report.write_text(render_report(results, plots, options.out), encoding="utf-8")
        drawn = sum(path.endswith(".png") for path in plots.values())
        err.write(f"wrote {options.out / 'metrics.json'}, {report} and {drawn} figures\n")
    return EXIT_OK


@dataclass(frozen=True)
class RerunOptions:
    """Options of ``smm-bag rerun``."""

    bag: Path
    params_files: Sequence[Path] = field(default_factory=tuple)
    json: bool = False
    out: Path | None = None
    expect_equal: bool = False
    tolerance: float | None = None
    """Per-step relative tolerance; None: what a bag from another machine passes; 0: bit for bit."""
    window: TimeWindow = field(default_factory=TimeWindow)
    quiet: bool = False


def rerun_command(options: RerunOptions, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """``smm-bag rerun BAG --params-file F``: offline chain beside the recorded commands and estimates."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        tolerance = tolerance_for(options.tolerance)
    except ValueError as error:
        err.write(f"smm-bag: error: --tolerance: {error}\n")
        return EXIT_USAGE
    try:
        progress = Progress(f"reading {options.bag.name}", 1, err, enabled=not options.quiet)
        run = load_run(options.bag, progress=progress, window=options.window)
        recorded = next(
            (
                {str(k): v for k, v in values.items()}
                for node, values in run.manifest.parameters.items()
                if node.rstrip("/").split("/")[-1] == "controller_node"
            ),
            {},
        )
        parameters = {**recorded, **read_params_files(options.params_files, run.manifest.namespace)}
        settings = chain_settings(parameters, run.manifest.controller or "fpdeso")
        result = rerun(run, settings)
    except BagError as error:
        return fail(error, err)
    except ParamsFileError as error:
        err.write(f"smm-bag: error: {error}\n")
        return EXIT_PARAMS
    agreement = judge(
        result.t_ns,
        result.command,
        result.recorded_command,
        flip_size=settings.flip_size,
        tolerance=tolerance,
        estimate=result.estimate,
        recorded_estimate=result.recorded_estimate,
    )
    difference = np.abs(result.command - result.recorded_command)
    summary: dict[str, object] = {
        "bag": str(options.bag),
        "window": options.window.describe(),
        "algorithm": settings.algorithm,
        "params_files": [str(p) for p in options.params_files],
        "steps": int(result.t_ns.size),
        "applied_torque_from": result.applied_source,
        "command_max_abs_difference_Nm": [float(v) for v in difference.max(axis=0)],
        "command_rms_offline_Nm": [float(v) for v in np.sqrt(np.mean(result.command**2, axis=0))],
        "command_rms_recorded_Nm": [float(v) for v in np.sqrt(np.mean(result.recorded_command**2, axis=0))],
    }
    if result.recorded_estimate is not None:
        summary["estimate_max_abs_difference_Nm"] = [
            float(v) for v in np.abs(result.estimate - result.recorded_estimate).max(axis=0)
        ]
    summary["tolerance"] = {
        "relative": tolerance.relative,
        "flip_share": tolerance.flip_share,
        "index_relative": tolerance.index_relative,
    }
    summary["command_tolerance_Nm"] = list(agreement.command_allowed)
    summary["sign_flips"] = [len(steps) for steps in agreement.flip_steps]
    summary["sign_flip_steps"] = [list(steps) for steps in agreement.flip_steps]
    summary["index_max_relative_difference"] = agreement.index_relative_difference
    summary["reproduces_recording"] = agreement.ok
    if options.json:
        out.write(json.dumps(summary, indent=2) + "\n")
    else:
        for key, value in summary.items():
            out.write(f"{key}: {value}\n")
    if options.out is not None:
        options.out.mkdir(parents=True, exist_ok=True)
        columns = {
            "t_ns": result.t_ns,
            "command_offline": result.command,
            "command_recorded": result.recorded_command,
            "estimate_offline": result.estimate,
        }
        if result.recorded_estimate is not None:
            columns["estimate_recorded"] = result.recorded_estimate
        header = ["t_ns"]
        table: list[np.ndarray] = [result.t_ns.astype(np.float64).reshape(-1, 1)]
        for name, values in columns.items():
            if name == "t_ns":
                continue
            header += [f"{name}_alpha", f"{name}_beta"]
            table.append(values)
        np.savetxt(
            options.out / "rerun.csv",
            np.hstack(table),
            delimiter=",",
            header=",".join(header),
            comments="",
            fmt="%.17g",
        )
        err.write(f"wrote {options.out / 'rerun.csv'}\n")
    if options.expect_equal and not agreement.ok:
        err.write(
            f"smm-bag: the re-run does not reproduce the recording (commands differ by up to "
            f"{float(difference.max()):.3g} N m; tolerance relative {tolerance.relative:g}):\n"
        )
        for reason in agreement.failures:
            err.write(f"  {reason}\n")
        return EXIT_CHECK_FAILED
    return EXIT_OK
