"""``smm-bag``: info, analyze, play, rerun, repair and identify on rosbag2 MCAP bags."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from smm_analysis.identify_command import BagAccess, add_identify_parser, identify_command

from smm_bag import commands
from smm_bag.errors import BagError
from smm_bag.lockstep import LockstepOptions
from smm_bag.player import PlayOptions, parse_remaps
from smm_bag.recorded import load_run

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``smm-bag``."""
    parser = argparse.ArgumentParser(
        prog="smm-bag",
        description="Inspect, analyse, re-run and repair rosbag2 MCAP bags of the SMM stack.",
        epilog="Exit codes: 0 ok, 1 check failed, 2 usage, 3 not a bag, 4 truncated (run repair), "
        "5 corrupt, 6 missing topics, 7 bad parameters file.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    info = sub.add_parser("info", help="what `ros2 bag info` prints, plus the run manifest and loss report")
    info.add_argument("bag", type=Path)

    analyze = sub.add_parser("analyze", help="SPEC section 5 indices per bag; several bags side by side")
    analyze.add_argument("bags", type=Path, nargs="+", metavar="BAG")
    analyze.add_argument("--json", action="store_true", help="print metrics.json's schema instead of a table")
    analyze.add_argument("--out", type=Path, help="write metrics.json, REPORT.md and PNG figures here")
    analyze.add_argument("--no-plots", action="store_true", help="with --out: no figures")
    analyze.add_argument("--quiet", action="store_true", help="no progress bar")

    rerun = sub.add_parser(
        "rerun", help="the control chain offline on the recorded measurements, other gains"
    )
    rerun.add_argument("bag", type=Path)
    rerun.add_argument(
        "--params-file", type=Path, action="append", default=[], help="ROS parameters file (repeatable)"
    )
    rerun.add_argument("--json", action="store_true", help="print the comparison as JSON")
    rerun.add_argument("--out", type=Path, help="write rerun.csv (offline and recorded, per step) here")
    rerun.add_argument(
        "--expect-equal",
        action="store_true",
        help="exit 1 if the offline commands differ from the recorded ones by more than --tolerance",
    )
    rerun.add_argument("--tolerance", type=float, default=0.0, help="N m (default 0: bit for bit)")

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

    repair = sub.add_parser("repair", help="rebuild summaries, indexes and metadata.yaml after a crash")
    repair.add_argument("bag", type=Path)
    repair.add_argument("--no-backup", action="store_true", help="do not keep damaged files as *.damaged")
    add_identify_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``smm-bag``; returns the exit code."""
    options = build_parser().parse_args(argv)
    if options.command == "info":
        return commands.info(options.bag)
    if options.command == "analyze":
        return commands.analyze(
            commands.AnalyzeOptions(
                bags=tuple(options.bags),
                json=options.json,
                out=options.out,
                plots=not options.no_plots,
                quiet=options.quiet or options.json,
            )
        )
    if options.command == "rerun":
        return commands.rerun_command(
            commands.RerunOptions(
                bag=options.bag,
                params_files=tuple(options.params_file),
                json=options.json,
                out=options.out,
                expect_equal=options.expect_equal,
                tolerance=options.tolerance,
            )
        )
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
            return commands.EXIT_USAGE
        return commands.play_command(options.bag, play_options)
    if options.command == "identify":
        return identify_command(options, BagAccess(load_run, (BagError,), commands.exit_code))
    return commands.repair(options.bag, backup=not options.no_backup)


if __name__ == "__main__":
    sys.exit(main())
