"""``smm_bench_emulator``: the bench in a box on loopback UDP (docs/HW_PROTOCOL.md, docs/NODES.md)."""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
from smm_hw_bridge.run_verdict import EXIT_NOT_CONTROLLED, VerdictConfig

from smm_bench_emulator.bench_file import default_bench, load_bench_file
from smm_bench_emulator.board import BoardConfig
from smm_bench_emulator.canopen_run import run_canopen
from smm_bench_emulator.emulator import Emulator, EmulatorConfig

__all__ = ["build_parser", "main", "run"]


def _endpoint(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        raise argparse.ArgumentTypeError(f"expected ADDRESS:PORT, got {text!r}")
    return host, int(port)


def build_parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(prog="smm_bench_emulator", description=__doc__)
    parser.add_argument("--bind", type=_endpoint, default=("127.0.0.1", 50101), help="board UDP address")
    parser.add_argument("--host", type=_endpoint, default=("127.0.0.1", 50100), help="bridge UDP address")
    parser.add_argument("--control", type=_endpoint, default=("127.0.0.1", 50102), help="JSON control port")
    parser.add_argument("--mode", choices=("realtime", "lockstep"), default="realtime")
    parser.add_argument(
        "--link",
        choices=("frame", "canopen"),
        default="frame",
        help="frame: the I/O board on UDP; canopen: CiA 408 valves and CiA 406 encoders on udp_multicast "
        "(SYNC from the bridge; refused unless the group routes over lo)",
    )
    parser.add_argument("--can-group", default="239.74.163.2", help="canopen: the IPv4 multicast group")
    parser.add_argument("--can-port", type=int, default=43113, help="canopen: the UDP port")
    parser.add_argument(
        "--lockstep-trigger",
        choices=("any", "enabled"),
        default="any",
        help="lockstep: tick on any answer, or only on an enabled one (runs line up with the simulator's)",
    )
    parser.add_argument(
        "--duration", type=float, default=0.0, help="stop after this many seconds of board time"
    )
    parser.add_argument(
        "--bench-file",
        default="",
        help="the bench description (YAML, docs/BENCH.md); the bench options below override its fields",
    )
    parser.add_argument("--counts-per-rev", type=int, help="default 2**20")
    parser.add_argument("--noise-std", type=float, help="position noise (rad), default 0")
    parser.add_argument("--inertia-scale", type=float, help="default 1")
    parser.add_argument("--disturbance", choices=("none", "eq46"), help="default none")
    parser.add_argument("--no-valve-lag", action="store_true", help="valves follow the D/A without lag")
    parser.add_argument("--full-scale-torque", type=float, help="N m at D/A code 32767, default 10")
    parser.add_argument(
        "--seed", type=int, help="seed of the plant's, the A/D's and the link's noise, default 0"
    )
    parser.add_argument("--control-period", type=float, help="board tick (s), default 0.001")
    parser.add_argument(
        "--control-divider",
        type=int,
        default=1,
        help="board ticks per control period: the run is judged per period; in lockstep only every Nth "
        "tick waits for the host",
    )
    parser.add_argument("--record", default="", help="write the per-tick record (.npz) here at the end")
    parser.add_argument("--status-file", default="", help="write the end-of-run status (JSON) here too")
    parser.add_argument(
        "--late-limit",
        type=float,
        default=VerdictConfig.late_limit * 100,
        help="percent of late enabled ticks (after --settle) above which the run did not control (exit 3)",
    )
    parser.add_argument(
        "--settle", type=float, default=VerdictConfig.settle_s, help="seconds of live output not judged"
    )
    parser.add_argument(
        "--start-timeout",
        type=float,
        default=0.0,
        help="seconds without a first step (lockstep) or a first live tick (realtime) after which the run "
        "never started (exit 3); 0 = none",
    )
    parser.add_argument(
        "--min-idle-us",
        type=int,
        default=EmulatorConfig.min_idle_ns // 1000,
        help="realtime: the least time the loop waits between two ticks when behind (us); 0 = back to back",
    )
    parser.add_argument(
        "--duration-from",
        choices=("boot", "live"),
        default="boot",
        help="count --duration from boot, or from the first tick that latched an enabled command",
    )
    return parser


def bench(args: argparse.Namespace) -> BoardConfig:
    """The bench: the ``--bench-file`` (or the defaults) with the fields the bench options name replaced.

    Raises:
        BenchFileError: The file cannot be read or describes no valid bench.
        ValueError: An option's value is out of its field's range.
    """
    base = load_bench_file(args.bench_file) if args.bench_file else default_bench()
    plant: dict[str, Any] = {}
    board: dict[str, Any] = {}
    if args.counts_per_rev is not None:
        plant["encoder_counts_per_rev"] = args.counts_per_rev
    if args.noise_std is not None:
        plant["noise_std"] = (args.noise_std, args.noise_std)
    if args.inertia_scale is not None:
        plant["inertia_scale"] = args.inertia_scale
    if args.disturbance is not None:
        plant["disturbance"] = args.disturbance
    if args.no_valve_lag:
        plant["valve_time_constants"] = None
    if args.control_period is not None:
        plant["control_period"] = args.control_period
    if args.seed is not None:
        plant["seed"] = board["seed"] = args.seed
    if args.full_scale_torque is not None:
        board["full_scale_torque"] = (args.full_scale_torque, args.full_scale_torque)
    return dataclasses.replace(base, plant=dataclasses.replace(base.plant, **plant), **board)


def config_from_args(args: argparse.Namespace) -> EmulatorConfig:
    """The emulator's configuration from its parsed options (the bench: :func:`bench`).

    Raises:
        BenchFileError: The bench file cannot be read or describes no valid bench.
        ValueError: An invalid value (the message names it).
    """
    board = bench(args)
    return EmulatorConfig(
        board=board,
        bind=args.bind,
        host=args.host,
        control=args.control,
        mode=args.mode,
        lockstep_trigger=args.lockstep_trigger,
        duration_ticks=round(args.duration * 1e9 / board.plant.period_ns),
        seed=board.seed if args.seed is None else args.seed,
        verdict=VerdictConfig(late_limit=args.late_limit / 100, settle_s=args.settle),
        start_timeout_ns=round(args.start_timeout * 1e9),
        duration_from_live=args.duration_from == "live",
        min_idle_ns=args.min_idle_us * 1000,
        control_divider=args.control_divider,
    )


def run(args: argparse.Namespace) -> int:
    """Builds and runs the emulator; returns the exit code (3: the run did not control, why on stderr)."""
    if args.link == "canopen":
        try:
            board = config_from_args(args).board
        except ValueError as error:
            print(f"smm_bench_emulator: {error}", file=sys.stderr)
            return 2
        return run_canopen(
            board,
            args.can_group,
            args.can_port,
            lockstep=args.mode == "lockstep",
            divider=args.control_divider,
            duration_s=args.duration,
            start_timeout_s=args.start_timeout,
            status_file=args.status_file,
        )
    try:
        emulator = Emulator(config_from_args(args), record=bool(args.record))
    except (ValueError, OSError) as error:
        print(f"smm_bench_emulator: {error}", file=sys.stderr)
        return 2

    def stop(signum: int, frame: FrameType | None) -> None:
        emulator.running = False

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    print(
        f"smm_bench_emulator: session {emulator.board.session:#010x}, {args.mode}, board {args.bind}",
        flush=True,
    )
    try:
        emulator.run()
    finally:
        emulator.close()
    if args.record and emulator.record is not None:
        rows = np.asarray(emulator.record, dtype=np.float64).reshape(-1, 5)
        np.savez(args.record, tick=rows[:, 0].astype(np.int64), position=rows[:, 1:3], codes=rows[:, 3:5])
    status = emulator.status()
    summary = json.dumps(status)
    if args.status_file:
        Path(args.status_file).write_text(summary)
    print(f"smm_bench_emulator: {status['figures']}", flush=True)
    print(summary, flush=True)
    if status["verdict"] is not None:
        print(
            f"smm_bench_emulator: the run did not control: {status['verdict']}", file=sys.stderr, flush=True
        )
        return EXIT_NOT_CONTROLLED
    return 0


def ros_parameters() -> dict[str, str]:
    """``-p`` names that smm-launch may pass: every option of :func:`build_parser` taking a value."""
    return {
        option[2:]: option
        for action in build_parser()._actions
        if action.nargs != 0
        for option in action.option_strings
        if option.startswith("--")
    }


def from_ros_arguments(argv: Sequence[str]) -> list[str]:
    """Options from ``--ros-args -p name:=value ...`` (how smm-launch starts every process of the graph).

    ``-p`` names of :func:`ros_parameters` become the options of the same name; remappings and parameter
    files are ignored (the emulator is not a ROS node).

    Raises:
        ValueError: an unknown ``-p`` name.
    """
    if "--ros-args" not in argv:
        return list(argv)
    index = list(argv).index("--ros-args")
    options, ros = list(argv[:index]), list(argv[index + 1 :])
    for flag, value in itertools.pairwise(ros):
        if flag == "-p":
            name, _, text = value.partition(":=")
            known = ros_parameters()
            if name not in known:
                raise ValueError(f"unknown parameter {name!r} (known: {sorted(known)})")
            options += [known[name], text.strip('"')]
    return options


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point."""
    try:
        options = from_ros_arguments(sys.argv[1:] if argv is None else argv)
    except ValueError as error:
        print(f"smm_bench_emulator: {error}", file=sys.stderr)
        return 2
    return run(build_parser().parse_args(options))


if __name__ == "__main__":
    sys.exit(main())
