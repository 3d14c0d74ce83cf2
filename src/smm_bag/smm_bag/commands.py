"""The ``smm-bag`` commands: each takes parsed options, prints, and returns an exit code.

Exit codes: 0 done; 1 a check failed (rerun differs where equality was asked for); 2 usage or invalid
input; 3 not a bag; 4 truncated bag (repair it); 5 corrupt bag; 6 missing topics; 7 bad parameters file;
8 repair could save nothing of a storage file (the file is left as it was).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from smm_bag.analysis import comparison_table, evaluate, metrics_document
from smm_bag.errors import (
    BagError,
    CorruptBagError,
    MissingTopicsError,
    NotABagError,
    ParamsFileError,
    TruncatedBagError,
    UnsalvageableFileError,
)
from smm_bag.info import format_info
from smm_bag.lockstep import LockstepOptions, LockstepResult, play_lockstep
from smm_bag.player import PlayOptions, PlayResult, play
from smm_bag.plots import write_plots
from smm_bag.progress import Progress
from smm_bag.recorded import load_run
from smm_bag.repair import repair_bag
from smm_bag.repair_report import format_repair
from smm_bag.report import render_report
from smm_bag.rerun import chain_settings, read_params_files, rerun

__all__ = [
    "EXIT_CHECK_FAILED",
    "EXIT_CORRUPT",
    "EXIT_MISSING_TOPICS",
    "EXIT_NOT_A_BAG",
    "EXIT_OK",
    "EXIT_PARAMS",
    "EXIT_TRUNCATED",
    "EXIT_UNSALVAGEABLE",
    "EXIT_USAGE",
    "AnalyzeOptions",
    "RerunOptions",
    "analyze",
    "exit_code",
    "info",
    "play_command",
    "repair",
    "rerun_command",
]

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_USAGE = 2
EXIT_NOT_A_BAG = 3
EXIT_TRUNCATED = 4
EXIT_CORRUPT = 5
EXIT_MISSING_TOPICS = 6
EXIT_PARAMS = 7
EXIT_UNSALVAGEABLE = 8


def exit_code(error: BagError) -> int:
    """The exit code of a library error."""
    for kind, code in (
        (NotABagError, EXIT_NOT_A_BAG),
        (TruncatedBagError, EXIT_TRUNCATED),
        (CorruptBagError, EXIT_CORRUPT),
        (MissingTopicsError, EXIT_MISSING_TOPICS),
        (ParamsFileError, EXIT_PARAMS),
        (UnsalvageableFileError, EXIT_UNSALVAGEABLE),
    ):
        if isinstance(error, kind):
            return code
    return EXIT_USAGE


def _fail(error: BagError, stderr: TextIO) -> int:
    stderr.write(f"smm-bag: error: {error}\n")
    return exit_code(error)


def info(bag: Path, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """``smm-bag info BAG``."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        out.write(format_info(bag) + "\n")
    except BagError as error:
        return _fail(error, err)
    return EXIT_OK


def repair(
    bag: Path, *, backup: bool = True, stdout: TextIO | None = None, stderr: TextIO | None = None
) -> int:
    """``smm-bag repair BAG``: rebuild damaged files and metadata.yaml; prints per file what was lost.

    Exit 0 when every file is intact or repaired, 8 when nothing could be saved of a file (left as it was).
    """
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        report = repair_bag(bag, backup=backup, progress=lambda name: print(f"checking {name}", file=err))
    except BagError as error:
        return _fail(error, err)
    out.write(format_repair(report) + "\n")
    for failure in report.errors:
        err.write(f"smm-bag: error: {failure}\n")
    return exit_code(report.errors[0]) if report.errors else EXIT_OK


@dataclass(frozen=True)
class AnalyzeOptions:
    """Options of ``smm-bag analyze``."""

    bags: Sequence[Path]
    json: bool = False
    out: Path | None = None
    plots: bool = True
    quiet: bool = False


def analyze(options: AnalyzeOptions, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """``smm-bag analyze BAG [BAG...]``: indices (table or ``--json``), figures and report into ``--out``."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    results = []
    try:
        for bag in options.bags:
            progress = Progress(f"reading {bag.name}", 1, err, enabled=not options.quiet)
            results.append(evaluate(load_run(bag, progress=progress)))
    except BagError as error:
        return _fail(error, err)
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
    if options.out is not None:
        options.out.mkdir(parents=True, exist_ok=True)
        (options.out / "metrics.json").write_text(json.dumps(document, indent=2, allow_nan=False) + "\n")
        plots = write_plots([r.run for r in results], options.out) if options.plots else {}
        report = options.out / "REPORT.md"
        report.write_text(render_report(results, plots, options.out), encoding="utf-8")
        figures = sum(path.endswith(".png") for path in plots.values())
        err.write(f"wrote {options.out / 'metrics.json'}, {report} and {figures} figures\n")
    return EXIT_OK


@dataclass(frozen=True)
class RerunOptions:
    """Options of ``smm-bag rerun``."""

    bag: Path
    params_files: Sequence[Path] = field(default_factory=tuple)
    json: bool = False
    out: Path | None = None
    expect_equal: bool = False
    tolerance: float = 0.0


def rerun_command(options: RerunOptions, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """``smm-bag rerun BAG --params-file F``: offline chain beside the recorded commands and estimates."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        run = load_run(options.bag, progress=Progress(f"reading {options.bag.name}", 1, err))
        recorded = next(
            (
                {str(k): v for k, v in values.items()}
                for node, values in run.manifest.parameters.items()
                if node.rstrip("/").split("/")[-1] == "controller_node"
            ),
            {},
        )
        parameters = {**recorded, **read_params_files(options.params_files)}
        settings = chain_settings(parameters, run.manifest.controller or "fpdeso")
        result = rerun(run, settings)
    except BagError as error:
        return _fail(error, err)
    difference = np.abs(result.command - result.recorded_command)
    summary: dict[str, object] = {
        "bag": str(options.bag),
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
    if options.expect_equal and float(difference.max()) > options.tolerance:
        err.write(
            f"smm-bag: offline commands differ from the recorded ones by up to "
            f"{float(difference.max()):.3g} N m (tolerance {options.tolerance:g})\n"
        )
        return EXIT_CHECK_FAILED
    return EXIT_OK


def play_command(
    bag: Path,
    options: PlayOptions | LockstepOptions,
    ros_args: Sequence[str] = (),
    stderr: TextIO | None = None,
) -> int:
    """``smm-bag play BAG [--lockstep]``: publish the bag until its end (or SIGINT/SIGTERM when looping).

    Lockstep: exits 1 when an answer timed out.
    """
    import signal  # noqa: PLC0415

    import rclpy  # noqa: PLC0415
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
    from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415

    from smm_node_runtime import ensure_localhost_discovery  # noqa: PLC0415

    err = stderr or sys.stderr
    ensure_localhost_discovery()
    stop = {"requested": False}

    def request_stop(_signum: int, _frame: object) -> None:
        stop["requested"] = True

    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    context = rclpy.Context()  # type: ignore[attr-defined]
    rclpy.init(args=["smm-bag", *ros_args], context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("smm_bag_player", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    result: PlayResult | LockstepResult
    try:
        progress = Progress(f"playing {bag.name}", 1, err)
        if isinstance(options, LockstepOptions):
            result = play_lockstep(
                bag, node, executor, options, should_stop=lambda: stop["requested"], progress=progress
            )
        else:
            result = play(bag, node, options, should_stop=lambda: stop["requested"], progress=progress)
    except BagError as error:
        return _fail(error, err)
    finally:
        executor.shutdown()
        node.destroy_node()  # type: ignore[no-untyped-call]
        context.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    for topic, count in result.published.items():
        err.write(f"{topic}: {count} messages published\n")
    if isinstance(result, LockstepResult):
        answered = sum(stamp in result.answers for stamp in result.stamps)
        err.write(
            f"{len(result.stamps)} stamps played, {answered} answered, {len(result.timeouts)} timed out\n"
        )
        if result.timeouts:
            shown = ", ".join(str(stamp) for stamp in result.timeouts[:5])
            err.write(f"smm-bag: no answer within the timeout for stamps (ns) {shown}\n")
            return EXIT_CHECK_FAILED
    return EXIT_OK
