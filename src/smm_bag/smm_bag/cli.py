"""``smm-bag``: info, play, repair, convert; other packages add subcommands (``smm_bag.commands``).

An entry point of that group names a function that takes the subparsers and adds one subcommand whose
``handler`` default maps the parsed options to an exit code (``smm_analysis`` adds ``analyze`` and ``rerun``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from importlib.metadata import entry_points
from pathlib import Path

from smm_bag import commands
from smm_bag.exit_codes import EXIT_USAGE
from smm_bag.lockstep import LockstepOptions
from smm_bag.player import PlayOptions, parse_remaps

__all__ = ["COMMAND_GROUP", "build_parser", "main"]

COMMAND_GROUP = "smm_bag.commands"
"""Entry-point group of the subcommands other packages add to ``smm-bag``."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``smm-bag``."""
    parser = argparse.ArgumentParser(
        prog="smm-bag",
        description="Inspect, analyse, re-run, repair and convert rosbag2 bags (MCAP, sqlite3) of SMM runs.",
        epilog="Exit codes: 0 ok, 1 check failed, 2 usage, 3 not a bag, 4 truncated (run repair), "
        "5 corrupt, 6 missing topics, 7 bad parameters file, 8 repair saved nothing of a file, "
        "9 storage not read (ROS 1).",
    )
    parser.set_defaults(handler=None)
    sub = parser.add_subparsers(dest="command", required=True)

    info = sub.add_parser("info", help="what `ros2 bag info` prints, plus the run manifest and loss report")
    info.add_argument("bag", type=Path)

    play = sub.add_parser("play", help="publish the bag with its original timing and QoS (ROS 2 graph)")
    play.add_argument("bag", type=Path)
    play.add_argument("--rate", type=float, default=1.0, help="speed factor (default 1)")
    play.add_argument("--loop", action="store_true", help="play again at the end until stopped")
    play.add_argument("--start-offset", type=float, default=0.0, help="skip this many seconds (s)")
    play.add_argument("--topics", nargs="+", default=[], help="only these topics")
    play.add_argument("--remap", nargs="+", default=[], metavar="OLD:=NEW", help="publish OLD as NEW")
    play.add_argument("--clock", action="store_true", help="publish /clock from the bag's time")
    play.add_argument("--clock-period", type=float, default=0.01, help="period of that /clock (s)")
    play.add_argument(
        "--wait-for-subscribers", type=float, default=0.0, help="wait up to this long for subscribers (s)"
    )
    play.add_argument(
        "--lockstep",
        metavar="ANSWER_TOPIC",
        default=None,
        help="flow-controlled replay into a node: publish the --topics messages of one stamp, wait for the "
        "node's answer with that stamp on ANSWER_TOPIC (or --answer-timeout), then the next stamp",
    )
    play.add_argument("--answer-timeout", type=float, default=1.0, help="lockstep: wait per answer (s)")

    repair = sub.add_parser(
        "repair", help="keep every chunk whose CRC checks; rebuild damaged files and metadata.yaml"
    )
    repair.add_argument("bag", type=Path)
    repair.add_argument("--no-backup", action="store_true", help="do not keep damaged files as *.damaged")

    convert = sub.add_parser("convert", help="write a bag (sqlite3 or MCAP) as a new MCAP bag")
    convert.add_argument("bag", type=Path)
    convert.add_argument("output", type=Path, help="the new bag folder (must not exist)")
    convert.add_argument("--compression", choices=("none", "zstd"), default="none", help="MCAP chunks")

    for entry in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        try:
            entry.load()(sub)
        except (ImportError, AttributeError) as error:  # a package installed in part: no such subcommand
            print(f"smm-bag: subcommand {entry.name!r} unavailable: {error}", file=sys.stderr)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``smm-bag``; returns the exit code."""
    options = build_parser().parse_args(argv)
    if options.command == "info":
        return commands.info(options.bag)
    if options.command == "convert":
        return commands.convert(options.bag, options.output, compression=options.compression)
    if options.handler is not None:
        code: int = options.handler(options)
        return code
    if options.command == "play":
        try:
            play_options: PlayOptions | LockstepOptions
            if options.lockstep is not None:
                play_options = LockstepOptions(
                    answer_topic=options.lockstep,
                    topics=tuple(options.topics),
                    remaps=parse_remaps(options.remap),
                    timeout_s=options.answer_timeout,
                    wait_for_subscribers_s=options.wait_for_subscribers or 10.0,
                )
            else:
                play_options = PlayOptions(
                    rate=options.rate,
                    loop=options.loop,
                    start_offset_s=options.start_offset,
                    topics=tuple(options.topics),
                    remaps=parse_remaps(options.remap),
                    clock=options.clock,
                    clock_period_s=options.clock_period,
                    wait_for_subscribers_s=options.wait_for_subscribers,
                )
        except ValueError as error:
            print(f"smm-bag: error: {error}", file=sys.stderr)
            return EXIT_USAGE
        return commands.play_command(options.bag, play_options)
    return commands.repair(options.bag, backup=not options.no_backup)


if __name__ == "__main__":
    sys.exit(main())
