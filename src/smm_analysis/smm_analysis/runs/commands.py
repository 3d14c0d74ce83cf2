"""``smm-bag analyze`` and ``smm-bag rerun``: each takes its options, prints, and returns an exit code."""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

from smm_bag.errors import BagError, MissingTopicsError
from smm_bag.exit_codes import EXIT_CHECK_FAILED, EXIT_CORRUPT, EXIT_OK, EXIT_PARAMS, EXIT_USAGE, fail
from smm_bag.progress import Progress

from smm_analysis.errors import ParamsFileError, UnknownParameterError
from smm_analysis.runs.agreement import Agreement, Tolerance, tolerance_for
from smm_analysis.runs.indices import comparison_table, evaluate_stream, metrics_document
from smm_analysis.runs.plots import RunFigures, write_plots
from smm_analysis.runs.report import render_report
from smm_analysis.runs.rerun import CONTROLLER_NODE, chain_settings, read_params_files
from smm_analysis.runs.rerun_stream import RerunCsv, rerun_stream, survey
from smm_analysis.runs.segments import MIN_SEGMENT_NS, Segment, find_segments, parameter_values
from smm_analysis.runs.stream import AHEAD_LIMIT_NS, StepStream
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


def _windows(
    bag: Path, window: TimeWindow, segments: bool, quiet: bool, err: TextIO
) -> list[tuple[TimeWindow, Segment | None]]:
    """The windows to read in ``bag``: ``window``, or each segment's for ``--segments``."""
    if not segments:
        return [(window, None)]
    search = find_segments(bag, progress=Progress(f"reading {bag.name}", 1, err, enabled=not quiet))
    if search.short_segments or search.disarmed_steps:
        err.write(
            f"{bag}: {len(search.segments)} segments; left out: {search.short_segments} shorter than "
            f"{MIN_SEGMENT_NS / 1e9:g} s, {search.disarmed_steps} disarmed steps\n"
        )
    if not search.segments:
        raise MissingTopicsError(f"{bag}: no segment of at least {MIN_SEGMENT_NS / 1e9:g} s")
    return [(segment.window, segment) for segment in search.segments]


def _stream(
    bag: Path, window: TimeWindow, segment: Segment | None, *, doing: str, quiet: bool, err: TextIO
) -> StepStream:
    """A stream of ``window`` with its progress bar (``doing`` the bag or the segment of it)."""
    what = bag.name if segment is None else f"segment {segment.number} of {bag.name}"
    label = f"{doing} {what}".strip()
    return StepStream(bag, window=window, progress=Progress(label, 1, err, enabled=not quiet))


def streams_of(
    bag: Path, *, window: TimeWindow, segments: bool, quiet: bool, err: TextIO
) -> list[tuple[StepStream, str | None]]:
    """The streams to read in ``bag``: the window, or each segment (with its label) for ``--segments``."""
    runs: list[tuple[StepStream, str | None]] = []
    for window_, segment in _windows(bag, window, segments, quiet, err):
        doing = "reading" if segment is None else ""
        stream = _stream(bag, window_, segment, doing=doing, quiet=quiet, err=err)
        label = None if segment is None else f"{stream.label} segment {segment.number} ({segment.reason})"
        runs.append((stream, label))
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
            for topic, count in sorted(result.run.ahead_messages.items()):
                out.write(
                    f"note: {result.run.bag}: {count} messages on {topic} were stamped more than "
                    f"{AHEAD_LIMIT_NS // 1_000_000_000} s after they were recorded (the preflight's "
                    "rehearsal, or a clock gone wrong) and were left out\n"
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
    segments: bool = False


def rerun_command(options: RerunOptions, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """``smm-bag rerun BAG --params-file F``: offline chain beside the recorded commands and estimates."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        tolerance = tolerance_for(options.tolerance)
    except ValueError as error:
        err.write(f"smm-bag: error: --tolerance: {error}\n")
        return EXIT_USAGE
    runs: list[tuple[dict[str, object], Agreement, str]] = []
    try:
        read_params_files(options.params_files, StepStream(options.bag).manifest.namespace)  # before reading
        for window, segment in _windows(options.bag, options.window, options.segments, options.quiet, err):
            runs.append(_rerun_window(options, window, segment, tolerance, err))
    except BagError as error:
        return fail(error, err)
    except UnknownParameterError as error:
        err.write(f"smm-bag: error: {error}\n")
        return EXIT_USAGE
    except ParamsFileError as error:
        err.write(f"smm-bag: error: {error}\n")
        return EXIT_PARAMS
    summaries = [summary for summary, _, _ in runs]
    if options.json:
        document: object = summaries if options.segments else summaries[0]
        out.write(json.dumps(document, indent=2) + "\n")
    else:
        for number, summary in enumerate(summaries):
            out.write("\n" if number else "")
            for key, value in summary.items():
                out.write(f"{key}: {value}\n")
    failed = False
    for _, agreement, prefix in runs:
        if options.expect_equal and not agreement.ok:
            failed = True
            err.write(
                f"smm-bag: {prefix}the re-run does not reproduce the recording (commands differ by up to "
                f"{max(agreement.command_max_difference):.3g} N m; tolerance relative "
                f"{tolerance.relative:g}):\n"
            )
            for reason in agreement.failures:
                err.write(f"  {reason}\n")
    return EXIT_CHECK_FAILED if failed else EXIT_OK


def _rerun_window(
    options: RerunOptions, window: TimeWindow, segment: Segment | None, tolerance: Tolerance, err: TextIO
) -> tuple[dict[str, object], Agreement, str]:
    """Re-runs one window: its summary, the verdict, and its name for messages (empty for the whole run).

    Raises:
        BagError: See :class:`StepStream`.
        ParamsFileError: A parameters file that cannot be read or holds invalid gains.
    """
    surveyed = _stream(options.bag, window, segment, doing="reading", quiet=options.quiet, err=err)
    manifest = surveyed.manifest
    recorded = next(
        (
            {str(k): v for k, v in values.items()}
            for node, values in manifest.parameters.items()
            if node.rstrip("/").split("/")[-1] == CONTROLLER_NODE
        ),
        {},
    )
    found = survey(surveyed)
    assert surveyed.report.first_ns is not None  # the survey raised on fewer than 2 steps
    recorded |= parameter_values(options.bag, CONTROLLER_NODE, surveyed.report.first_ns)
    parameters = {**recorded, **read_params_files(options.params_files, manifest.namespace)}
    settings = chain_settings(parameters, manifest.controller or "fpdeso")
    stream = _stream(options.bag, window, segment, doing="re-running", quiet=options.quiet, err=err)
    if options.out is None:
        result = rerun_stream(stream, settings, found, tolerance)
    else:
        options.out.mkdir(parents=True, exist_ok=True)
        name = "rerun.csv" if segment is None else f"rerun_segment_{segment.number}.csv"
        with RerunCsv(options.out / name, recorded_estimate=found.estimate_complete) as rows:
            result = rerun_stream(stream, settings, found, tolerance, rows)
        err.write(f"wrote {rows.path}\n")
    agreement = result.agreement
    summary: dict[str, object] = {"bag": str(options.bag)}
    if segment is not None:
        summary["segment"] = f"{segment.number} ({segment.reason})"
    summary |= {
        "window": window.describe(),
        "algorithm": settings.algorithm,
        "params_files": [str(p) for p in options.params_files],
        "steps": result.steps,
        "applied_torque_from": result.applied_source,
        "command_max_abs_difference_Nm": list(agreement.command_max_difference),
        "command_rms_offline_Nm": list(result.command_rms_offline),
        "command_rms_recorded_Nm": list(result.command_rms_recorded),
    }
    if agreement.estimate_max_difference is not None:
        summary["estimate_max_abs_difference_Nm"] = list(agreement.estimate_max_difference)
    summary["tolerance"] = {
        "relative": tolerance.relative,
        "flip_share": tolerance.flip_share,
        "index_relative": tolerance.index_relative,
    }
    summary["command_tolerance_Nm"] = list(agreement.command_allowed)
    summary["sign_flips"] = list(agreement.flip_counts)
    summary["sign_flip_steps"] = [list(steps) for steps in agreement.flip_steps]
    summary["index_max_relative_difference"] = agreement.index_relative_difference
    summary["reproduces_recording"] = agreement.ok
    return summary, agreement, "" if segment is None else f"segment {segment.number}: "
