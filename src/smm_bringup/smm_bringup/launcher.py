"""``smm-launch``: start the node graph of :func:`smm_bringup.graph.build_graph` without the ``ros2`` CLI.

Each node its own OS process, as ``ros2 launch`` starts it (:mod:`smm_bringup.supervisor`; ``--loop direct``:
``direct_loop`` hosts bridge and controller), or all in this process with ``--composed``
(:mod:`smm_bringup.composed`). Options, the closing ``board:`` and ``run:`` lines, shutdown and exit codes
(0 run complete, 1 a node failed, 2 bad configuration, 3 a hardware run that did not control, 4 refused to
arm at preflight, 128 + signal): docs/LAUNCH.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from smm_controller.laws import law_names

from smm_bringup.composed import launch_composed
from smm_bringup.errors import GraphError
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import EMULATOR_NODE, NodeSpec
from smm_bringup.graph_options import (
    CANOPEN_REALTIME_RATE_HZ,
    CHAIN_LAYOUTS,
    CLOCK_MODES,
    CONTROL_RATES_HZ,
    LINKS,
    LOOPS,
    PLANT_ALIASES,
    PLANTS,
    RECORD_SPLIT_DURATIONS,
    RECORD_SPLIT_SIZES,
    REFERENCE_PLACEMENTS,
    SCENARIO_NAMES,
    GraphOptions,
    default_control_rate,
)
from smm_bringup.supervisor import (
    EXIT_CONFIGURATION_ERROR,
    EXIT_NOT_CONTROLLED,
    EXIT_OK,
    EXIT_PREFLIGHT_REFUSED,
    STOP_GRACE_S,
    RespawnPolicy,
    _say,
    launch_processes,
    resolve_executable,
)

__all__ = [
    "build_parser",
    "main",
    "options_from_arguments",
    "run",
]


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface of ``smm-launch``."""
    parser = argparse.ArgumentParser(
        prog="smm-launch",
        description="Start the SMM control graph (simulator, TD, FLESO, reference, controller), one process "
        "per node like ros2 launch, or all in one process with --composed.",
    )
    parser.add_argument(
        "--plant",
        choices=(*PLANTS, *PLANT_ALIASES),
        default="sim",
        help="plant: sim (smm_sim_node) or hardware (hw_bridge_node + the bench emulator unless --board)",
    )
    parser.add_argument(
        "--board", default=None, help="hardware: ADDRESS:PORT of the I/O board (default: start the emulator)"
    )
    parser.add_argument(
        "--link",
        choices=LINKS,
        default=GraphOptions.link,
        help="hardware: frame (the I/O board's protocol) or canopen (CiA 408 valves, CiA 406 encoders, "
        "the emulated CANopen bench unless --board external)",
    )
    parser.add_argument(
        "--bench-file", default=None, help="hardware, emulator: the bench description (YAML, docs/BENCH.md)"
    )
    parser.add_argument(
        "--clock-mode",
        choices=CLOCK_MODES,
        default="lockstep",
        help="lockstep: each step waits for the controller's answer (simulator, or the emulator "
        "board-clocked over UDP); realtime: the plant's own clock",
    )
    parser.add_argument(
        "--chain",
        choices=CHAIN_LAYOUTS,
        default=GraphOptions.chain,
        help="fused: TD, FLESO and law in controller_node (2 hops per step); "
        "split: td_node and fleso_node as their own nodes (4 hops per step)",
    )
    parser.add_argument(
        "--reference",
        choices=REFERENCE_PLACEMENTS,
        default=GraphOptions.reference,
        help="controller: controller_node samples the reference itself (one process and one input less per "
        "step); node: reference_node publishes it",
    )
    parser.add_argument(
        "--loop",
        choices=LOOPS,
        default=GraphOptions.loop,
        help="hardware: topics (the bridge and controller_node as processes joined by topics) or direct "
        "(one process steps the chain in the bridge's receiving thread; topics for observation only); auto "
        "(default): direct in real time where the chain and reference allow it, else topics",
    )
    parser.add_argument("--algorithm", choices=law_names(), default="fpdeso", help="controller algorithm")
    parser.add_argument(
        "--scenario",
        choices=(*SCENARIO_NAMES, "none"),
        default="case2",
        help="scenario of SPEC section 3 (reference, noise, disturbance, model error); none = node defaults",
    )
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        help="simulated seconds until the simulator stops (default: the scenario's in lockstep, endless in "
        "realtime; 0 = endless)",
    )
    parser.add_argument("--seed", type=int, default=None, help="seed of the simulator's noise")
    parser.add_argument(
        "--control-rate",
        type=float,
        default=None,
        metavar="HZ",
        help=f"control rate, one of {', '.join(map(str, CONTROL_RATES_HZ))} Hz: the controller steps every "
        "1000/HZ ticks of the board's (or the simulator's) 1 kHz tick, the board holds each command between "
        f"(default 1000; {CANOPEN_REALTIME_RATE_HZ} with --link canopen in realtime)",
    )
    parser.add_argument(
        "--params-file",
        action="append",
        default=[],
        metavar="FILE",
        help="extra ROS 2 parameter file for every node (repeatable; applied after the scenario's)",
    )
    parser.add_argument(
        "--record",
        metavar="DIR",
        default=None,
        help="record every topic to a rosbag2 MCAP bag in DIR (new folder) with smm_bag's recorder_node",
    )
    parser.add_argument(
        "--record-max-size",
        type=int,
        default=0,
        metavar="BYTES",
        help="with --record: start a new bag file when the current one reaches BYTES "
        f"(0 = never, else {RECORD_SPLIT_SIZES[0]}..{RECORD_SPLIT_SIZES[1]})",
    )
    parser.add_argument(
        "--record-max-duration",
        type=float,
        default=0.0,
        metavar="S",
        help="with --record: start a new bag file after S seconds of messages "
        f"(0 = never, else {RECORD_SPLIT_DURATIONS[0]:g}..{RECORD_SPLIT_DURATIONS[1]:g})",
    )
    parser.add_argument(
        "--rt-priority",
        type=int,
        default=None,
        metavar="N",
        help="SCHED_FIFO priority of the loop's processes, 0 = normal scheduling (default: 50 with --plant "
        "hardware, 0 with the simulator); the emulator runs 20 above, the recorder 10 below",
    )
    parser.add_argument(
        "--late-limit",
        type=float,
        default=GraphOptions.late_limit,
        metavar="PERCENT",
        help="hardware, and the simulator in real time: exit 3 (did not control) when more than this "
        "percentage of the control periods after the first second live were late or not live",
    )
    parser.add_argument(
        "--preflight",
        type=float,
        default=None,
        metavar="S",
        help="hardware, real time: seconds the bridge rehearses the loop with output disabled before arming "
        "(0-30, 0 skips it; default 3); a rate this host does not hold is refused (exit 4)",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="hardware: arm even when the preflight finds the control rate is not held (with a warning)",
    )
    parser.add_argument(
        "--start-timeout",
        type=float,
        default=GraphOptions.start_timeout,
        metavar="S",
        help="hardware lockstep: exit 3 (never started) when no step came within S seconds",
    )
    parser.add_argument(
        "--respawn",
        action="store_true",
        help="restart a node process that exits while the graph runs (as launch's respawn), every node but "
        "the recorder, a plant that completed its run and a process that refused to arm at preflight "
        "(exit 4: final)",
    )
    parser.add_argument(
        "--respawn-delay",
        type=float,
        default=RespawnPolicy.delay_s,
        metavar="S",
        help="with --respawn: seconds between a node's exit and its restart, in [0, 60]",
    )
    parser.add_argument(
        "--respawn-limit",
        type=int,
        default=RespawnPolicy.limit,
        metavar="N",
        help="with --respawn: restarts allowed per node, in [1, 10000]; the next exit stops the graph",
    )
    parser.add_argument("--composed", action="store_true", help="run all nodes in this process")
    parser.add_argument(
        "--dry-run",
        action="store_true",
        help="print the node command lines (full paths, quoted for a POSIX shell) and exit",
    )
    parser.add_argument(
        "--stop-grace",
        type=float,
        default=STOP_GRACE_S,
        metavar="S",
        help="seconds each stop signal (SIGINT, then SIGTERM) gets before the next",
    )
    return parser


def options_from_arguments(arguments: argparse.Namespace) -> GraphOptions:
    """Turn parsed arguments into :class:`GraphOptions`.

    Raises:
        ValueError: An invalid combination or value (message from GraphOptions).
    """
    return GraphOptions(
        plant=arguments.plant,
        clock_mode=arguments.clock_mode,
        chain=arguments.chain,
        reference=arguments.reference,
        algorithm=arguments.algorithm,
        scenario=None if arguments.scenario == "none" else arguments.scenario,
        duration=arguments.duration,
        seed=arguments.seed,
        params_files=tuple(arguments.params_file),
        control_rate=(
            default_control_rate(arguments.link, arguments.clock_mode)
            if arguments.control_rate is None
            else arguments.control_rate
        ),
        board=arguments.board,
        link=arguments.link,
        bench_file=arguments.bench_file,
        record=arguments.record,
        record_max_size=arguments.record_max_size,
        record_max_duration=arguments.record_max_duration,
        rt_priority=arguments.rt_priority,
        loop=arguments.loop,
        late_limit=arguments.late_limit,
        start_timeout=arguments.start_timeout,
        preflight=arguments.preflight,
        force=arguments.force,
    )


def arguments_from_options(options: GraphOptions) -> list[str]:
    """The ``smm-launch`` arguments of the graph ``options`` describe; inverts options_from_arguments."""
    arguments = ["--plant", options.plant, "--clock-mode", options.clock_mode, "--chain", options.chain]
    arguments += ["--reference", options.reference, "--algorithm", options.algorithm]
    arguments += ["--scenario", "none" if options.scenario is None else options.scenario]
    if options.duration is not None:
        arguments += ["--duration", repr(options.duration)]
    if options.seed is not None:
        arguments += ["--seed", str(options.seed)]
    if options.control_rate != default_control_rate(options.link, options.clock_mode):
        arguments += ["--control-rate", str(options.control_rate)]
    for params_file in options.params_files:
        arguments += ["--params-file", params_file]
    if options.board is not None:
        arguments += ["--board", options.board]
    if options.link != GraphOptions.link:
        arguments += ["--link", options.link]
    if options.bench_file is not None:
        arguments += ["--bench-file", options.bench_file]
    if options.record is not None:
        arguments += ["--record", options.record]
    if options.record_max_size:
        arguments += ["--record-max-size", str(options.record_max_size)]
    if options.record_max_duration:
        arguments += ["--record-max-duration", repr(options.record_max_duration)]
    if options.rt_priority is not None:
        arguments += ["--rt-priority", str(options.rt_priority)]
    arguments += ["--loop", options.loop]
    if options.preflight is not None:
        arguments += ["--preflight", repr(options.preflight)]
    if options.force:
        arguments.append("--force")
    if options.late_limit != GraphOptions.late_limit:
        arguments += ["--late-limit", repr(options.late_limit)]
    if options.start_timeout != GraphOptions.start_timeout:
        arguments += ["--start-timeout", repr(options.start_timeout)]
    return arguments


def run(argv: Sequence[str]) -> int:
    """Parse ``argv``, build the graph and run it; return the exit code (module docstring)."""
    arguments = build_parser().parse_args(list(argv))
    try:
        options = options_from_arguments(arguments)
        if options.loop_note is not None:
            _say(options.loop_note)
        specs = build_graph(options)
        respawn = respawn_from_arguments(arguments)
        if respawn is not None and arguments.composed:
            raise ValueError("--respawn restarts processes: it cannot be combined with --composed")
        if arguments.dry_run:
            for spec in specs:
                print(shlex.join(spec.command_line(resolve_executable(spec))))
            return EXIT_OK
        if arguments.composed:
            return launch_composed(specs)
        if options.plant != "hardware":
            return launch_processes(specs, stop_grace_s=arguments.stop_grace, respawn=respawn)
        with tempfile.TemporaryDirectory(prefix="smm-launch-") as folder:
            status = Path(folder) / "board.json"
            code = launch_processes(
                with_board_status(specs, status), stop_grace_s=arguments.stop_grace, respawn=respawn
            )
            if code == EXIT_PREFLIGHT_REFUSED:
                _say("run: refused to arm at preflight (the bridge's figures and reason above)", sys.stderr)
                return code
            _say(board_line(status, real_board=options.board is not None))
            read = read_line(status)
            if read and options.board is None:
                _say(read)
            verdict = None if options.board is not None else verdict_line(status)
            if verdict is not None:
                _say(verdict, sys.stderr if verdict.startswith("run: did not control") else None)
                if code == EXIT_OK and verdict.startswith("run: did not control"):
                    return EXIT_NOT_CONTROLLED
            return code
    except (GraphError, ValueError) as error:
        _say(f"error: {error}", sys.stderr)
        return EXIT_CONFIGURATION_ERROR


def respawn_from_arguments(arguments: argparse.Namespace) -> RespawnPolicy | None:
    """The respawn policy of ``--respawn``/``--respawn-delay``/``--respawn-limit`` (None without it).

    Raises:
        ValueError: A delay or limit out of range, or one given without ``--respawn``.
    """
    if not arguments.respawn:
        if (arguments.respawn_delay, arguments.respawn_limit) != (RespawnPolicy.delay_s, RespawnPolicy.limit):
            raise ValueError("--respawn-delay and --respawn-limit are options of --respawn")
        return None
    return RespawnPolicy(arguments.respawn_delay, arguments.respawn_limit)


def with_board_status(specs: Sequence[NodeSpec], path: Path) -> tuple[NodeSpec, ...]:
    """``specs`` with the bench emulator writing its end-of-run status to ``path``."""
    return tuple(
        dataclasses.replace(spec, parameters=(*spec.parameters, ("status-file", str(path))))
        if spec.name == EMULATOR_NODE
        else spec
        for spec in specs
    )


def board_line(path: Path, *, real_board: bool) -> str:
    """The closing line of a hardware run, from the emulator's status at ``path`` (docs/LAUNCH.md).

    ``board: late L of N enabled ticks (P %), feedback->command p50 A us, p99 B us``; with a real board,
    what the host can know instead, and where.
    """
    if real_board:
        return (
            "board: a real board's tick counters are not read by smm-launch; the host's view (the board's "
            "late count from its feedback frames, receive->send) is in hw_bridge_node's /diagnostics and, "
            "with --loop direct, in direct_loop's closing 'host:' line"
        )
    try:
        status = json.loads(path.read_text())
        late, enabled = int(status["late_commands"]), int(status["enabled_ticks"])
        p50, p99 = status["latency_p50_us"], status["latency_p99_us"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        return f"board: no end-of-run status from the emulator ({type(error).__name__}: {error})"
    percent = 100.0 * late / enabled if enabled else 0.0
    figures = "no enabled command" if p50 is None else f"p50 {p50:.0f} us, p99 {p99:.0f} us"
    divider = int(status.get("control_divider", 1))
    held = f" (its count per tick: it holds {divider - 1} of every {divider})" if divider > 1 else ""
    late_line = f"board: late {late} of {enabled} enabled ticks ({percent:.2f} %){held}"
    return f"{late_line}, feedback->command {figures}"


def verdict_line(path: Path) -> str | None:
    """``run: controlled (figures)`` or ``run: did not control: reason (figures)``, from the emulator."""
    try:
        status = json.loads(path.read_text())
        figures, reason = str(status["figures"]), status["verdict"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if reason is None:
        return f"run: controlled ({figures})"
    return f"run: did not control: {reason} ({figures})"


def read_line(path: Path) -> str | None:
    """When the emulator's process read the commands (its own wake-up included), beside the arrival line."""
    try:
        status = json.loads(path.read_text())
        p50, p99 = status["read_latency_p50_us"], status["read_latency_p99_us"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if p50 is None:
        return None
    return (
        f"board: (arrival is the kernel's receive time; the emulator process read them at p50 {p50:.0f} us, "
        f"p99 {p99:.0f} us, its own wake-up included)"
    )


def main() -> int:
    """Console script ``smm-launch``."""
    return run(sys.argv[1:])


if __name__ == "__main__":
    sys.exit(main())
