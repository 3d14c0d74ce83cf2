"""``smm-sweep SPEC.yaml [--out DIR] [--workers N] [--scheduler ADDRESS] [--rerun ID]`` (docs/SWEEPS.md).

This module parses, then calls :func:`smm_bringup.sweep.command.sweep` or
:func:`~smm_bringup.sweep.command.rerun`.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from pathlib import Path

from smm_bringup.sweep.command import SweepOptions, rerun, sweep
from smm_bringup.sweep.execute import default_workers

__all__ = ["build_parser", "main"]


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a number >= 1, got {value}")
    return value


def _run_id(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a run id (whole number >= 0), got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a run id >= 0, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``smm-sweep``."""
    parser = argparse.ArgumentParser(
        prog="smm-sweep",
        description="Gain studies on the batched closed loop: grids, random and Latin-hypercube draws, plant "
        "draws for robustness; Parquet, Pareto front, robustness percentiles, plots, report and the chosen "
        "gains as a ROS parameters file.",
    )
    parser.add_argument("spec", type=Path, help="sweep spec (YAML; docs/SWEEPS.md)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default out/sweeps/<name>)")
    parser.add_argument(
        "--workers", type=_positive, default=None, help="local processes (default: the cores)"
    )
    parser.add_argument("--scheduler", default=None, help="Dask scheduler address, e.g. tcp://HOST:8786")
    parser.add_argument("--rerun", type=_run_id, default=None, help="re-run this run id with the scalar loop")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``smm-sweep``; returns the exit code."""
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    args = build_parser().parse_args(argv)
    options = SweepOptions(
        spec=args.spec,
        out=args.out,
        workers=args.workers if args.workers is not None else default_workers(),
        scheduler=args.scheduler,
        rerun=args.rerun,
    )
    return rerun(options) if options.rerun is not None else sweep(options)


if __name__ == "__main__":
    raise SystemExit(main())
