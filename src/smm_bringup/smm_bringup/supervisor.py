"""The process supervisor of ``smm-launch``: start the graph's processes, watch them, stop and reap them all.

Exit codes and the stop sequence are those of ``smm-launch`` (``smm_bringup.launcher``, ``docs/LAUNCH.md``).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any, Final, TextIO

from ament_index_python.packages import PackageNotFoundError, get_package_prefix
from smm_hw_bridge.idle_states import CPU_DMA_LATENCY, IdleStateHold, hold_idle_states
from smm_hw_bridge.preflight import EXIT_PREFLIGHT_REFUSED
from smm_hw_bridge.run_verdict import EXIT_NOT_CONTROLLED

from smm_bringup.errors import GraphError
from smm_bringup.graph_nodes import PLANT_NODE_NAMES, RECORDER_NODE, RUN_ENDERS, NodeSpec, expected_publishers
from smm_bringup.realtime import (
    OBSERVER_NICE,
    Scheduling,
    fifo,
    fifo_allowed,
    nice,
    observer_fifo_allowed,
)

__all__ = [
    "EXIT_CONFIGURATION_ERROR",
    "EXIT_NODE_FAILED",
    "EXIT_NOT_CONTROLLED",
    "EXIT_OK",
    "EXIT_PREFLIGHT_REFUSED",
    "ExecutableNotFoundError",
    "GraphProcesses",
    "RespawnPolicy",
    "hold_idle_states_for",
    "launch_processes",
    "resolve_executable",
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


@dataclass(frozen=True)
class RespawnPolicy:
    """``--respawn``: restart a node process that exited, as launch's ``respawn``/``respawn_delay``.

    Every node but the recorder (its bag folder exists) is restarted with its command line when it exits
    while the graph runs, unless it is a plant process that completed the run (exit 0), a process that ended
    a run that did not control (exit 3: a safety stop is final) or refused to arm at preflight (exit 4:
    final until a person changes something; a respawn would refuse again).

    Attributes:
        delay_s: Seconds between the exit and the restart, in [0, 60].
        limit: Restarts allowed per node, in [1, 10000]; one more exit stops the graph (exit 1).
    """

    delay_s: float = 1.0
    limit: int = 10

    def __post_init__(self) -> None:
        delay = self.delay_s
        if isinstance(delay, bool) or not isinstance(delay, (int, float)) or not 0.0 <= delay <= 60.0:
            raise ValueError(f"respawn delay must be a number of seconds in [0, 60], got {delay!r}")
        limit = self.limit
        if isinstance(limit, bool) or not isinstance(limit, int) or not 1 <= limit <= 10_000:
            raise ValueError(f"respawn limit must be an int in [1, 10000], got {limit!r}")

    def applies(self, spec: NodeSpec, code: int) -> bool:
        """True when a node ``spec`` that exited with ``code`` is to be restarted."""
        completed = spec.name in RUN_ENDERS and code == EXIT_OK
        final = code in (EXIT_NOT_CONTROLLED, EXIT_PREFLIGHT_REFUSED)
        return spec.name != RECORDER_NODE and not completed and not final


@dataclass
class _Child:
    spec: NodeSpec
    popen: subprocess.Popen[bytes]
    command: tuple[str, ...] = ()
    scheduling: Scheduling = field(default_factory=Scheduling)
    respawns: int = 0
    restart_at: float | None = None

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

    def _spawn(self, command: Sequence[str], scheduling: Scheduling) -> subprocess.Popen[bytes]:
        return subprocess.Popen(
            list(command),
            env=self._env,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
            preexec_fn=scheduling.preexec(),  # noqa: PLW1509 (no threads yet)
        )

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
        schedulings = _schedulings(specs)
        for index, (spec, command) in enumerate(zip(specs, commands, strict=True)):
            scheduling = schedulings.get(spec.name, Scheduling())
            popen = self._spawn(command, scheduling)
            self.children.append(_Child(spec, popen, tuple(command), scheduling))
            _say(f"started {spec.name} (pid {popen.pid}{scheduling.describe()}): {' '.join(command)}")
            if spec is recorder:
                _wait_for_recorder(spec, popen)
            elif (
                recorder is not None and index + 1 < len(specs) and specs[index + 1].name in PLANT_NODE_NAMES
            ):
                _wait_for_recorded_publishers(recorder, expected_publishers(specs), popen)

    def first_exit(self) -> tuple[NodeSpec, int] | None:
        """The first child found exited and its exit code (negative: killed by that signal); None if none.

        A child waiting to be respawned is not reported again.
        """
        for child in self.children:
            code = child.popen.poll()
            if code is not None and child.restart_at is None:
                return child.spec, code
        return None

    def schedule_respawn(self, spec: NodeSpec, code: int, policy: RespawnPolicy) -> bool:
        """Plans the restart of the exited node ``spec`` after ``policy.delay_s``; False past the limit."""
        child = next(child for child in self.children if child.spec is spec)
        if child.respawns >= policy.limit:
            _say(
                f"node {spec.name} exited with code {code} after {child.respawns} respawns (the limit)",
                sys.stderr,
            )
            return False
        child.respawns += 1
        child.restart_at = time.monotonic() + policy.delay_s
        _say(
            f"node {spec.name} exited with code {code}; respawning it in {policy.delay_s:g} s "
            f"({child.respawns} of {policy.limit})",
            sys.stderr,
        )
        return True

    def respawn_due(self) -> None:
        """Restarts every child whose respawn delay has passed."""
        now = time.monotonic()
        for child in self.children:
            if child.restart_at is not None and now >= child.restart_at:
                child.restart_at = None
                child.popen = self._spawn(child.command, child.scheduling)
                _say(f"respawned {child.name} (pid {child.popen.pid}): {' '.join(child.command)}")

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


def _schedulings(specs: Sequence[NodeSpec]) -> dict[str, Scheduling]:
    """``{node: scheduling}`` of the specs asking for SCHED_FIFO, if the system allows it (else says so).

    A recorder without the CPUs for SCHED_FIFO gets normal policy with :data:`OBSERVER_NICE` instead.
    """
    wanted = {spec.name: spec.rt_priority for spec in specs if spec.rt_priority}
    if wanted and not fifo_allowed(max(wanted.values())):
        _say(
            f"cannot use SCHED_FIFO (priority {max(wanted.values())}) here: it needs CAP_SYS_NICE or an "
            "rtprio limit (docs/NODES.md, 'Real time'); running every node at normal priority",
            sys.stderr,
        )
        return {}
    schedulings = {name: fifo(priority) for name, priority in wanted.items()}
    cpus = len(os.sched_getaffinity(0))
    loop = len(wanted) - (RECORDER_NODE in wanted)
    if RECORDER_NODE in wanted and not observer_fifo_allowed(loop, cpus):
        schedulings[RECORDER_NODE] = nice(OBSERVER_NICE)
        _say(
            f"{RECORDER_NODE} at normal policy, nice {OBSERVER_NICE}: {loop} loop process(es) under "
            f"SCHED_FIFO on {cpus} CPU(s); a real-time recorder would share their CPUs and the kernel's RT "
            f"budget (it needs {loop + 2} CPUs: docs/SOAK.md, 'Real time beside the loop')"
        )
    under_fifo = sum(scheduling.priority > 0 for scheduling in schedulings.values())
    if under_fifo >= cpus:
        _say(
            f"{under_fifo} processes under SCHED_FIFO on {cpus} CPU(s): when they need more CPU than there "
            "is, they starve every other process and the kernel's RT throttling stops them all, the emulator "
            "included, for up to 50 ms a second (docs/LAUNCH.md, 'Real time on a small machine'); "
            "--rt-priority 0 runs them at normal priority",
            sys.stderr,
        )
    return schedulings


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
    respawn: RespawnPolicy | None = None,
) -> int:
    """Run the graph as separate processes until the plant completes, a node dies, or a stop signal.

    Args:
        specs: The graph (:func:`~smm_bringup.graph.build_graph`).
        env: Environment of the children (default: ours, see :func:`child_environment`).
        stop_grace_s: Seconds each stop signal gets before the next one.
        respawn: Restart nodes that exit (:class:`RespawnPolicy`); None: a node's exit stops the graph.

    Returns:
        The exit code (module docstring).

    Raises:
        ExecutableNotFoundError: A console script is missing (nothing is started then).
    """
    processes = GraphProcesses(specs, child_environment(env), stop_grace_s)
    request = _StopRequest()
    with _stop_signals(request), hold_idle_states_for(specs):
        try:
            processes.start()
            while not request.event.wait(_POLL_S):
                processes.respawn_due()
                exited = processes.first_exit()
                if exited is None:
                    continue
                spec, code = exited
                if respawn is not None and respawn.applies(spec, code):
                    if processes.schedule_respawn(spec, code, respawn):
                        continue
                elif (spec.name in RUN_ENDERS and code == EXIT_OK) or (
                    spec.name in PLANT_NODE_NAMES and code == EXIT_NOT_CONTROLLED
                ):
                    ended = "completed its run" if code == EXIT_OK else "ended the run: it did not control"
                    _say(f"{spec.name} {ended}; stopping the graph")
                    codes = processes.stop()
                    _report_stop(codes, expected_done=spec.name)
                    return EXIT_NOT_CONTROLLED if EXIT_NOT_CONTROLLED in codes.values() else EXIT_OK
                if code == EXIT_NOT_CONTROLLED:  # the loop ended its run (a safety stop): final
                    _say(f"{spec.name} ended the run: it did not control (why: above); stopping the graph")
                    _report_stop(processes.stop(), expected_done=spec.name)
                    return EXIT_NOT_CONTROLLED
                if code == EXIT_PREFLIGHT_REFUSED:
                    final = (
                        " (not respawned: final until a person changes a setting or the load)"
                        if respawn is not None
                        else ""
                    )
                    _say(f"{spec.name} refused to arm at preflight{final}; stopping the graph", sys.stderr)
                    _report_stop(processes.stop(), expected_done=spec.name)
                    return EXIT_PREFLIGHT_REFUSED
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


@contextlib.contextmanager
def hold_idle_states_for(specs: Sequence[NodeSpec], device: Path = CPU_DMA_LATENCY) -> Any:
    """While a real-time run (a node asks for SCHED_FIFO) lasts: ``device`` held at 0, said either way."""
    if not any(spec.rt_priority for spec in specs):
        yield None
        return
    hold: IdleStateHold = hold_idle_states(0, device)
    _say(hold.statement, None if hold.held else sys.stderr)
    try:
        yield hold
    finally:
        if hold.held:
            hold.close()
            _say(f"idle states: released {device}")


def _report_stop(codes: Mapping[str, int], expected_done: str | None = None) -> None:
    clean = {0, -signal.SIGINT, 128 + signal.SIGINT}
    for name, code in codes.items():
        if code == EXIT_NOT_CONTROLLED:
            _say(f"{name}: the run did not control (exit code {code}; its reason above)", sys.stderr)
        elif name != expected_done and code not in clean:
            _say(f"node {name} did not stop cleanly (exit code {code})", sys.stderr)
