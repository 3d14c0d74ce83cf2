"""``smm-sweep SPEC.yaml [--out DIR] [--workers N] [--scheduler ADDRESS] [--rerun ID]`` (docs/SWEEPS.md).

This module parses, then calls :func:`smm_analysis.sweep.command.sweep` or
:func:`~smm_analysis.sweep.command.rerun`.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from smm_analysis.sweep.command import SweepOptions, rerun, sweep
from smm_analysis.sweep.execute import default_workers

__all__ = ["build_parser", "main"]


def _whole(minimum: int) -> Callable[[str], int]:
    """An argparse type: a whole number >= ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"expected a number >= {minimum}, got {value}")
        return value

    return parse


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
        "--workers", type=_whole(1), default=None, help="local processes (default: the cores)"
    )
    parser.add_argument("--scheduler", default=None, help="Dask scheduler address, e.g. tcp://HOST:8786")
    parser.add_argument("--rerun", type=_whole(0), default=None, help="re-run this run with the scalar loop")
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
