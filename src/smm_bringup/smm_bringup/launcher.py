"""``smm-launch``: start the SMM node graph without the ``ros2`` CLI (which PyPI does not provide).

It starts the graph that :func:`smm_bringup.graph.build_graph` describes, the same one the launch files
start on a full ROS 2 install:

* by default each node is its own OS process, like ``ros2 launch``: the installed console script with
  ``--ros-args -r __ns:=/smm -r __node:=<name> --params-file F ... -p key:=value ...``, in a process group
  of its own;
* with ``--composed`` all nodes run in this process, in one executor (the EventsExecutor when available),
  built from the node classes with the same parameter values.

Shutdown and exit codes (see ``docs/LAUNCH.md``):

* the plant node exits 0 when its run is complete (``duration`` reached): the other nodes are stopped and
  ``smm-launch`` exits 0;
* any other node exit (or a non-zero plant exit) is reported with the node's name and exit code, the graph
  is stopped and ``smm-launch`` exits 1;
* Ctrl-C (SIGINT) or SIGTERM: every child's process group gets SIGINT, then SIGTERM, then SIGKILL, each
  after a grace period; all children are reaped; the exit code is 128 + the signal number;
* a configuration error (unknown option value, ``--plant hardware`` in lockstep or composed, a missing
  executable or parameter file) exits 2 before anything starts.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any, Final, TextIO

import rclpy
from ament_index_python.packages import PackageNotFoundError, get_package_prefix
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions

from smm_bringup.graph import (
    ALGORITHMS,
    CHAIN_LAYOUTS,
    CLOCK_MODES,
    EMULATOR_NODE,
    LOOPS,
    NAMESPACE,
    PLANT_ALIASES,
    PLANT_NODE_NAMES,
    PLANTS,
    RECORDER_NODE,
    REFERENCE_PLACEMENTS,
    SCENARIO_NAMES,
    GraphError,
    GraphOptions,
    NodeSpec,
    build_graph,
    expected_publishers,
    parameter_overrides,
)
from smm_bringup.realtime import fifo_allowed, fifo_preexec
from smm_node_runtime import as_parameter_list, ensure_localhost_discovery, make_executor

__all__ = [
    "EXIT_CONFIGURATION_ERROR",
    "EXIT_NODE_FAILED",
    "EXIT_OK",
    "ExecutableNotFoundError",
    "GraphProcesses",
    "build_parser",
    "launch_composed",
    "launch_processes",
    "main",
    "options_from_arguments",
    "resolve_executable",
    "run",
]

EXIT_OK: Final[int] = 0
EXIT_NODE_FAILED: Final[int] = 1
EXIT_CONFIGURATION_ERROR: Final[int] = 2
DISCOVERY_RANGE_VARIABLE: Final[str] = "ROS_AUTOMATIC_DISCOVERY_RANGE"
STOP_GRACE_S: Final[float] = 5.0
"""Seconds each stop signal (SIGINT, then SIGTERM) gets before the next, harsher one is sent."""
_POLL_S: Final[float] = 0.05


class ExecutableNotFoundError(GraphError):
    """A node's console script is not installed (run ``make setup`` or ``colcon build``)."""


def _say(message: str, stream: TextIO | None = None) -> None:
    print(f"[smm-launch] {message}", file=stream or sys.stdout, flush=True)


def executable_candidates(spec: NodeSpec) -> list[Path]:
    """Where ``ros2 run`` would look for the console script of ``spec``, then the interpreter's bin dir.

    ament_python packages install their scripts to ``<prefix>/lib/<package>/`` (``setup.cfg``); the prefix
    is the package's ament prefix on a colcon install and ``sys.prefix`` in this virtual environment.
    """
    prefixes: list[Path] = []
    with contextlib.suppress(PackageNotFoundError, OSError):  # OSError: no AMENT_PREFIX_PATH
        prefixes.append(Path(get_package_prefix(spec.package)))
    prefixes.append(Path(sys.prefix))
    candidates = [prefix / "lib" / spec.package / spec.executable for prefix in prefixes]
    candidates.append(Path(sys.executable).parent / spec.executable)
    return candidates


def resolve_executable(spec: NodeSpec) -> str:
    """Find the console script of ``spec`` (:func:`executable_candidates`, then PATH).

    Raises:
        ExecutableNotFoundError: It is nowhere.
    """
    candidates = executable_candidates(spec)
    for candidate in candidates:
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return str(candidate)
    found = shutil.which(spec.executable)
    if found is None:
        tried = ", ".join(str(path) for path in candidates)
        raise ExecutableNotFoundError(
            f"executable {spec.executable!r} of package {spec.package} not found (tried {tried} and PATH); "
            "install the packages (make setup)"
        )
    return found


def child_environment(base: Mapping[str, str] | None = None) -> dict[str, str]:
    """Environment of the node processes: ``base`` (default: ours) with discovery kept on this machine."""
    env = dict(os.environ if base is None else base)
    env.setdefault(DISCOVERY_RANGE_VARIABLE, "LOCALHOST")
    env["PYTHONUNBUFFERED"] = "1"
    return env


class _StopRequest:
    """Records the first SIGINT/SIGTERM received (signal handlers only set it)."""

    def __init__(self) -> None:
        self.signal_number: int | None = None
        self.event = threading.Event()

    def handler(self, signum: int, _frame: FrameType | None) -> None:
        if self.signal_number is None:
            self.signal_number = signum
        self.event.set()


@contextlib.contextmanager
def _stop_signals(request: _StopRequest) -> Any:
    previous = {sig: signal.signal(sig, request.handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield request
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@dataclass
class _Child:
    spec: NodeSpec
    popen: subprocess.Popen[bytes]

    @property
    def name(self) -> str:
        return self.spec.name


class GraphProcesses:
    """The node processes of one graph: start, supervise, stop (no signal handling of its own).

    Args:
        specs: Nodes to start, in order.
        env: Environment of the children (see :func:`child_environment`).
        stop_grace_s: Seconds each stop signal gets before the next one.
    """

    def __init__(self, specs: Sequence[NodeSpec], env: Mapping[str, str], stop_grace_s: float = STOP_GRACE_S):
        self._specs = tuple(specs)
        self._env = dict(env)
        self._grace = stop_grace_s
        self.children: list[_Child] = []

    def start(self) -> None:
        """Start every node in its own session (so a signal to its group reaches only it and its children).

        Raises:
            ExecutableNotFoundError: A console script is missing (nothing is started then).
        """
        specs = list(self._specs)
        recorder = next((spec for spec in specs if spec.name == RECORDER_NODE), None)
        if recorder is not None:
            # Recording: the recorder first, the plant last, once the recorder has matched every
            # controller-side publisher; the plant holds step 0 until its own publishers have matched
            # their readers, the recorder's included (start.min_subscribers, set by build_graph).
            specs.sort(key=lambda spec: (spec.name != RECORDER_NODE) + 2 * (spec.name in PLANT_NODE_NAMES))
        commands = [spec.command_line(resolve_executable(spec)) for spec in specs]
        fifo = _fifo_priorities(specs)
        for index, (spec, command) in enumerate(zip(specs, commands, strict=True)):
            priority = fifo.get(spec.name, 0)
            popen = subprocess.Popen(
                command,
                env=self._env,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
                preexec_fn=fifo_preexec(priority) if priority else None,  # noqa: PLW1509 (no threads yet)
            )
            self.children.append(_Child(spec, popen))
            scheduling = f", SCHED_FIFO {priority}" if priority else ""
            _say(f"started {spec.name} (pid {popen.pid}{scheduling}): {' '.join(command)}")
            if spec is recorder:
                _wait_for_recorder(spec, popen)
            elif (
                recorder is not None and index + 1 < len(specs) and specs[index + 1].name in PLANT_NODE_NAMES
            ):
                _wait_for_recorded_publishers(recorder, expected_publishers(specs), popen)

    def first_exit(self) -> tuple[NodeSpec, int] | None:
        """The first child found exited and its exit code (negative: killed by that signal); None if none."""
        for child in self.children:
            code = child.popen.poll()
            if code is not None:
                return child.spec, code
        return None

    def stop(self) -> dict[str, int]:
        """Stop every child still running: SIGINT to its group, then SIGTERM, then SIGKILL; reap all.

        A recorder is stopped after every other node, so that it records their last messages.

        Returns:
            ``{node name: exit code}`` of every child.
        """
        others = [child for child in self.children if child.name != RECORDER_NODE]
        recorders = [child for child in self.children if child.name == RECORDER_NODE]
        self._stop_children(others)
        if any(child.popen.poll() is None for child in recorders):
            time.sleep(RECORDER_SETTLE_S)  # let it write what it has received but not yet taken
        self._stop_children(recorders)
        codes = {}
        for child in self.children:
            codes[child.name] = child.popen.wait()
            # A node's own children (if any) share its process group: make sure none outlives it.
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(child.popen.pid, signal.SIGKILL)
        return codes

    def _stop_children(self, children: Sequence[_Child]) -> None:
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            running = [child for child in children if child.popen.poll() is None]
            if not running:
                break
            if sig != signal.SIGINT:
                names = ", ".join(child.name for child in running)
                _say(f"{names} still running after {self._grace:g} s: sending {signal.Signals(sig).name}")
            for child in running:
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(child.popen.pid, sig)
            deadline = time.monotonic() + self._grace
            for child in running:
                with contextlib.suppress(subprocess.TimeoutExpired):
                    child.popen.wait(timeout=max(0.0, deadline - time.monotonic()))


def _fifo_priorities(specs: Sequence[NodeSpec]) -> dict[str, int]:
    """``{node: SCHED_FIFO priority}`` of the specs asking for one, if the system allows it (else says so)."""
    wanted = {spec.name: spec.rt_priority for spec in specs if spec.rt_priority}
    if wanted and not fifo_allowed(max(wanted.values())):
        _say(
            f"cannot use SCHED_FIFO (priority {max(wanted.values())}) here: it needs CAP_SYS_NICE or an "
            "rtprio limit (docs/NODES.md, 'Real time'); running every node at normal priority",
            sys.stderr,
        )
        return {}
    return wanted


PUBLISHERS_FILE: Final[str] = ".publishers"
"""The recorder's file of matched publishers in its bag folder (``smm_bag.recorder_node.PUBLISHERS_FILE``)."""
RECORDER_SETTLE_S: Final[float] = 1.0
"""Time the recorder gets, after the other nodes stopped, to write its backlog before it is stopped (s)."""


def _recorder_output(spec: NodeSpec) -> Path | None:
    output = dict(spec.parameters).get("output")
    return Path(output) if isinstance(output, str) else None


def read_matched_publishers(marker: Path) -> dict[str, int]:
    """The recorder's ``.publishers`` file: matched publishers per topic ({} while it does not exist)."""
    counts: dict[str, int] = {}
    with contextlib.suppress(FileNotFoundError):
        for line in marker.read_text().splitlines():
            topic, _, count = line.rpartition(" ")
            if topic and count.isdigit():
                counts[topic] = int(count)
    return counts


def _wait_for_recorded_publishers(
    recorder: NodeSpec, expected: Mapping[str, int], popen: subprocess.Popen[bytes], timeout_s: float = 30.0
) -> None:
    """Wait until the recorder has matched ``expected`` publishers per topic (the controller side)."""
    output = _recorder_output(recorder)
    if output is None or not expected:
        return
    marker = output / PUBLISHERS_FILE
    deadline = time.monotonic() + timeout_s
    missing: dict[str, str] = {}
    while time.monotonic() < deadline and popen.poll() is None:
        matched = read_matched_publishers(marker)
        missing = {
            topic: f"{matched.get(topic, 0)}/{count}"
            for topic, count in expected.items()
            if matched.get(topic, 0) < count
        }
        if not missing:
            return
        time.sleep(0.02)
    shown = ", ".join(f"{topic} {counts}" for topic, counts in sorted(missing.items()))
    _say(f"the recorder has not matched every publisher within {timeout_s:g} s ({shown}); starting the plant")


def _wait_for_recorder(spec: NodeSpec, popen: subprocess.Popen[bytes], timeout_s: float = 20.0) -> None:
    """Wait until the recorder has opened its bag (and so subscribed), so that it sees the first step."""
    output = _recorder_output(spec)
    if output is None:
        return
    marker = output / "metadata.yaml"
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and popen.poll() is None and not marker.is_file():
        time.sleep(0.02)
    time.sleep(0.3)  # its subscriptions are created right after the bag is opened


def launch_processes(
    specs: Sequence[NodeSpec],
    *,
    env: Mapping[str, str] | None = None,
    stop_grace_s: float = STOP_GRACE_S,
) -> int:
    """Run the graph as separate processes until the plant completes, a node dies, or a stop signal.

    Args:
        specs: The graph (:func:`~smm_bringup.graph.build_graph`).
        env: Environment of the children (default: ours, see :func:`child_environment`).
        stop_grace_s: Seconds each stop signal gets before the next one.

    Returns:
        The exit code (module docstring).

    Raises:
        ExecutableNotFoundError: A console script is missing (nothing is started then).
    """
    processes = GraphProcesses(specs, child_environment(env), stop_grace_s)
    request = _StopRequest()
    with _stop_signals(request):
        try:
            processes.start()
            while not request.event.wait(_POLL_S):
                exited = processes.first_exit()
                if exited is None:
                    continue
                spec, code = exited
                if spec.name in PLANT_NODE_NAMES and code == 0:
                    _say(f"{spec.name} completed its run; stopping the graph")
                    _report_stop(processes.stop(), expected_done=spec.name)
                    return EXIT_OK
                _say(f"node {spec.name} exited with code {code}; stopping the graph", sys.stderr)
                _report_stop(processes.stop(), expected_done=spec.name)
                return EXIT_NODE_FAILED
            signum = request.signal_number or signal.SIGINT
            _say(f"received {signal.Signals(signum).name}; stopping the graph")
            _report_stop(processes.stop())
            return 128 + signum
        finally:
            # Whatever happened above (including an exception), no child may outlive the launcher.
            processes.stop()


def _report_stop(codes: Mapping[str, int], expected_done: str | None = None) -> None:
    clean = {0, -signal.SIGINT, 128 + signal.SIGINT}
    for name, code in codes.items():
        if name != expected_done and code not in clean:
            _say(f"node {name} did not stop cleanly (exit code {code})", sys.stderr)


def launch_composed(specs: Sequence[NodeSpec]) -> int:
    """Run every node of the graph in this process, in one executor.

    Each node class gets the parameter values its spec sets (files, then overrides) as
    ``parameter_overrides``; the namespace is applied as a global remapping of the context.

    Returns:
        0 when the plant completed its run, 128 + signal number after Ctrl-C / SIGTERM, 1 when a node
        failed (its exception is reported).
    """
    if any(not spec.node_class for spec in specs):
        names = [spec.name for spec in specs if not spec.node_class]
        raise GraphError(
            f"composed mode runs ROS nodes only; {names} must run as processes (drop --composed)"
        )
    ensure_localhost_discovery()
    context = Context()
    namespaces = {spec.namespace for spec in specs}
    if len(namespaces) != 1:
        raise GraphError(f"composed mode needs one namespace for all nodes, got {sorted(namespaces)}")
    # Signals are this function's to handle (one stop request, one exit code), not rclpy's.
    rclpy.init(
        args=["smm-launch", "--ros-args", "-r", f"__ns:=/{namespaces.pop() or NAMESPACE}"],
        context=context,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    nodes: list[Any] = []
    executor = None
    request = _StopRequest()
    try:
        for spec in specs:
            overrides = as_parameter_list(parameter_overrides(spec))
            try:
                node = spec.load_class()(context=context, parameter_overrides=overrides)
            except ValueError as error:
                raise GraphError(f"{spec.name}: invalid parameter: {error}") from error
            if node.get_name() != spec.name:
                raise GraphError(
                    f"{spec.node_class} created node {node.get_name()!r}, the graph expects {spec.name!r}"
                )
            nodes.append(node)
            _say(f"created {spec.name} ({spec.node_class}) in this process")
        executor = make_executor(context)
        for node in nodes:
            executor.add_node(node)
        plant = next((n for n, s in zip(nodes, specs, strict=True) if s.name in PLANT_NODE_NAMES), None)
        done = getattr(plant, "done", None)
        with _stop_signals(request):
            while not request.event.is_set() and context.ok():
                if done is not None:
                    executor.spin_until_future_complete(done, timeout_sec=_POLL_S * 4)
                    if done.done():
                        if done.exception() is not None:
                            _say(f"the plant failed: {done.exception()}", sys.stderr)
                            return EXIT_NODE_FAILED
                        _say("the plant completed its run; stopping the graph")
                        return EXIT_OK
                else:
                    executor.spin_once(timeout_sec=_POLL_S * 4)
        signum = request.signal_number or signal.SIGINT
        _say(f"received {signal.Signals(signum).name}; stopping the graph")
        return 128 + signum
    except (KeyboardInterrupt, ExternalShutdownException):
        return 128 + signal.SIGINT
    except GraphError:
        raise
    except Exception as error:  # a node's callback raised: report which, stop everything
        _say(f"a node failed: {type(error).__name__}: {error}", sys.stderr)
        return EXIT_NODE_FAILED
    finally:
        if executor is not None:
            executor.shutdown()
        for node in reversed(nodes):
            node.destroy_node()
        context.try_shutdown()


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
    parser.add_argument("--clock-mode", choices=CLOCK_MODES, default="lockstep", help="simulator clock mode")
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
        "(one process steps the chain in the bridge's receiving thread; topics for observation only)",
    )
    parser.add_argument("--algorithm", choices=ALGORITHMS, default="fpdeso", help="controller algorithm")
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
        "--control-period",
        type=float,
        default=None,
        metavar="S",
        help="control period of every node in seconds (default: as configured, 0.001)",
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
        "--rt-priority",
        type=int,
        default=None,
        metavar="N",
        help="SCHED_FIFO priority of the loop's processes, 0 = normal scheduling (default: 50 with --plant "
        "hardware, 0 with the simulator); the emulator runs 20 above, the recorder 10 below",
    )
    parser.add_argument("--composed", action="store_true", help="run all nodes in this process")
    parser.add_argument("--dry-run", action="store_true", help="print the node command lines and exit")
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
        control_period=arguments.control_period,
        board=arguments.board,
        record=arguments.record,
        rt_priority=arguments.rt_priority,
        loop=arguments.loop,
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
    if options.control_period is not None:
        arguments += ["--control-period", repr(options.control_period)]
    for params_file in options.params_files:
        arguments += ["--params-file", params_file]
    if options.board is not None:
        arguments += ["--board", options.board]
    if options.record is not None:
        arguments += ["--record", options.record]
    if options.rt_priority is not None:
        arguments += ["--rt-priority", str(options.rt_priority)]
    if options.loop != GraphOptions.loop:
        arguments += ["--loop", options.loop]
    return arguments


def run(argv: Sequence[str]) -> int:
    """Parse ``argv``, build the graph and run it; return the exit code (module docstring)."""
    arguments = build_parser().parse_args(list(argv))
    try:
        options = options_from_arguments(arguments)
        specs = build_graph(options)
        if arguments.dry_run:
            for spec in specs:
                print(" ".join([spec.executable, *spec.ros_arguments()]))
            return EXIT_OK
        if arguments.composed:
            return launch_composed(specs)
        if options.plant != "hardware":
            return launch_processes(specs, stop_grace_s=arguments.stop_grace)
        with tempfile.TemporaryDirectory(prefix="smm-launch-") as folder:
            status = Path(folder) / "board.json"
            code = launch_processes(with_board_status(specs, status), stop_grace_s=arguments.stop_grace)
            _say(board_line(status, real_board=options.board is not None))
            return code
    except (GraphError, ValueError) as error:
        _say(f"error: {error}", sys.stderr)
        return EXIT_CONFIGURATION_ERROR


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
    return f"board: late {late} of {enabled} enabled ticks ({percent:.2f} %), feedback->command {figures}"


def main() -> int:
    """Console script ``smm-launch``."""
    return run(sys.argv[1:])


if __name__ == "__main__":
    sys.exit(main())
