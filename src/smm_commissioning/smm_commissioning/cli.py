"""``smm-commission STEP --out DIR [--link canopen --params-file F] (--bench-file FILE | --board B)``.

Guided commissioning, on the frame link (``--board ADDRESS:PORT``) or the CANopen link (``--board
external``), or on either's emulated bench in this process (``--bench-file``).

The parsing layer: each subcommand's options, then :mod:`smm_commissioning.commands`. docs/COMMISSIONING.md.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from smm_commissioning.commands import (
    EXIT_USAGE,
    identify_command,
    jog_command,
    probe_command,
    tune_command,
    verify_command,
)
from smm_commissioning.link import EXTERNAL, LINKS
from smm_commissioning.probe import parse_pose

__all__ = ["main", "parser"]


def _pose(text: str) -> tuple[float, float]:
    try:
        return parse_pose(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from error


def _common(sub: argparse.ArgumentParser) -> None:
    sub.add_argument("--out", type=Path, required=True, help="directory of the state, reports, parameters")
    sub.add_argument(
        "--link", choices=LINKS, default="frame", help="frame: the I/O board; canopen: CiA 408 / 406 nodes"
    )
    bench = sub.add_mutually_exclusive_group(required=True)
    bench.add_argument(
        "--board",
        metavar="ADDRESS:PORT",
        help=f"the I/O board over UDP (frame protocol); with --link canopen '{EXTERNAL}': the real bus",
    )
    bench.add_argument(
        "--bench-file", type=Path, help="the emulated bench of this description, in this process, in lockstep"
    )
    sub.add_argument(
        "--params-file",
        type=Path,
        action="append",
        help="--link canopen: the bridge's parameter file with its canopen.* (repeatable, later wins)",
    )
    sub.add_argument("--bind", default="127.0.0.1:50100", metavar="ADDRESS:PORT", help="UDP: this host's end")
    sub.add_argument("--timeout", type=float, default=1.0, help="no feedback for this long stops (s)")
    sub.add_argument("--pose", type=_pose, default=(0.0, 0.0), help="'home' or 'ALPHA,BETA' (rad)")
    sub.add_argument("--ticks", type=int, default=2000, help="feedbacks probe reads")
    sub.add_argument("--supply-min", type=float, default=8.0, help="lowest supply pressure (bar)")


def parser() -> argparse.ArgumentParser:
    """The argument parser of ``smm-commission``."""
    top = argparse.ArgumentParser(prog="smm-commission", description=__doc__)
    steps = top.add_subparsers(dest="step", required=True)
    probe = steps.add_parser("probe", help="read the bench with the output disabled; name its faults")
    _common(probe)
    jog = steps.add_parser(
        "jog", help="open-loop pulses per joint: polarity, direction, deadband, bias, gains"
    )
    _common(jog)
    _motion(jog)
    jog.add_argument("--velocity-limit", type=float, default=1.5, help="largest speed (rad/s)")
    identify = steps.add_parser(
        "identify", help="the excitation closed on jog's parameters: the model, the valves' gains and null"
    )
    _common(identify)
    _motion(identify)
    identify.add_argument("--bootstrap", type=int, default=100, help="bootstrap replicates of the intervals")
    tune = steps.add_parser("tune", help="a gain sweep on the identified model (offline, nothing moves)")
    tune.add_argument("--out", type=Path, required=True, help="directory of the state, reports, parameters")
    tune.add_argument("--duration", type=float, default=2.0, help="case 1's length in the sweep (s)")
    tune.add_argument("--draws", type=int, default=3, help="plants drawn from the intervals per gain set")
    tune.add_argument("--seed", type=int, default=0, help="seed of the plant draws")
    tune.add_argument("--workers", type=int, default=1, help="local processes of the sweep")
    verify = steps.add_parser(
        "verify", help="case 1 closed on the commissioned parameters; writes commissioned.yaml when ready"
    )
    _common(verify)
    _motion(verify, window=False)
    verify.add_argument("--duration", type=float, default=5.0, help="case 1's length (s)")
    verify.add_argument(
        "--ready-factor", type=float, default=1.5, help="largest bench RMS over the model's for ready"
    )
    return top


def _motion(sub: argparse.ArgumentParser, window: bool = True) -> None:
    sub.add_argument("--confirm-motion", action="store_true", help="the joints will move: the bench is clear")
    if window:
        sub.add_argument("--window", type=float, default=0.2, help="largest excursion of a pulse (rad)")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: parses, runs the step, returns its exit code."""
    arguments = parser().parse_args(argv)
    if getattr(arguments, "timeout", 1.0) <= 0:
        print("smm-commission: --timeout must be > 0", file=sys.stderr)
        return EXIT_USAGE
    if arguments.step == "tune":
        return _configured(lambda: tune_command(arguments))
    commands = {
        "probe": probe_command,
        "jog": jog_command,
        "identify": identify_command,
        "verify": verify_command,
    }
    return _configured(lambda: commands[arguments.step](arguments))


def _configured(command: Callable[[], int]) -> int:
    """The command's exit code; an invalid option value (the step's config refuses it) is a usage error."""
    try:
        return command()
    except ValueError as error:
        print(f"smm-commission: {error}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
