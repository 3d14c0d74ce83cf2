"""The ``analyze`` and ``rerun`` subcommands of ``smm-bag`` (entry points of group ``smm_bag.commands``)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from smm_analysis.runs.commands import AnalyzeOptions, RerunOptions, analyze, rerun_command
from smm_analysis.runs.window import TimeWindow, add_reading_options, window_from_options

__all__ = ["add_analyze", "add_rerun"]


def add_analyze(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``smm-bag analyze BAG [BAG...]``."""
    parser = subparsers.add_parser(
        "analyze", help="SPEC section 5 indices per bag; several bags side by side"
    )
    parser.add_argument("bags", type=Path, nargs="+", metavar="BAG")
    parser.add_argument("--json", action="store_true", help="print metrics.json's schema instead of a table")
    parser.add_argument("--out", type=Path, help="write metrics.json, REPORT.md and PNG figures here")
    parser.add_argument("--no-plots", action="store_true", help="with --out: no figures")
    add_reading_options(
        parser,
        segments_help="find the experiments in each bag (armed stretches, parameter changes) and report each",
    )
    parser.set_defaults(
        handler=lambda options: _windowed(
            parser,
            options,
            lambda window: analyze(
                AnalyzeOptions(
                    bags=tuple(options.bags),
                    json=options.json,
                    out=options.out,
                    plots=not options.no_plots,
                    quiet=options.quiet or options.json,
                    window=window,
                    segments=options.segments,
                )
            ),
        )
    )


def _windowed(
    parser: argparse.ArgumentParser, options: argparse.Namespace, run: Callable[[TimeWindow], int]
) -> int:
    """Runs a command with the window of ``--start`` / ``--end``; a bad bound is a usage error."""
    try:
        window = window_from_options(options)
    except ValueError as error:
        parser.error(str(error))
    if getattr(options, "segments", False) and not window.whole:
        parser.error("--segments finds its own windows: give it without --start / --end")
    return run(window)


def add_rerun(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``smm-bag rerun BAG [--params-file F ...]``."""
    parser = subparsers.add_parser(
        "rerun", help="the control chain offline on the recorded measurements, other gains"
    )
    parser.add_argument("bag", type=Path)
    parser.add_argument(
        "--params-file", type=Path, action="append", default=[], help="ROS parameters file (repeatable)"
    )
    parser.add_argument("--json", action="store_true", help="print the comparison as JSON")
    parser.add_argument("--out", type=Path, help="write rerun.csv (offline and recorded, per step) here")
    parser.add_argument(
        "--expect-equal",
        action="store_true",
        help="exit 1 unless the offline commands and estimates reproduce the recorded ones (--tolerance)",
    )
    parser.add_argument(
        "--tolerance",
        type=float,
        default=None,
        metavar="RELATIVE",
        help="per-step tolerance, relative to the largest recorded |value| of each joint (default: what a "
        "bag recorded on another machine passes, 1e-9 and isolated sign flips; 0: bit for bit)",
    )
    add_reading_options(
        parser,
        segments_help="find the experiments in the bag (as analyze --segments) and re-run each alone",
    )
    parser.set_defaults(
        handler=lambda options: _windowed(
            parser,
            options,
            lambda window: rerun_command(
                RerunOptions(
                    bag=options.bag,
                    params_files=tuple(options.params_file),
                    json=options.json,
                    out=options.out,
                    expect_equal=options.expect_equal,
                    tolerance=options.tolerance,
                    window=window,
                    quiet=options.quiet or options.json,
                    segments=options.segments,
                )
            ),
        )
    )
