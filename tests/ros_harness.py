"""Helpers for tests that start ROS 2 nodes: private rclpy contexts, node processes, waiting for topics.

Every test that uses these runs inside the session's private network namespace (see ``conftest.py``) with
its own ``ROS_DOMAIN_ID``. Processes are started in their own session, so stopping one signals only its
process group, never anything this test did not start.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import signal
import subprocess
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

STOP_TIMEOUT_S = 10.0

DOMAIN_IDS = range(1, 200)
"""The ROS_DOMAIN_IDs a test session hands out in turn, one per test (Fast DDS takes 0-232)."""

_HELD_BLOCKS: list[int] = []
"""Open lock files of the blocks this process claimed: held until it ends."""


def worker_domain_ids(index: int, count: int) -> range:
    """The ``index``-th of ``count`` equal, disjoint blocks of :data:`DOMAIN_IDS`."""
    if not 0 <= index < count <= len(DOMAIN_IDS):
        raise ValueError(f"block {index} of {count}: needs 0 <= index < count <= {len(DOMAIN_IDS)}")
    size = len(DOMAIN_IDS) // count
    start = DOMAIN_IDS.start + index * size
    return range(start, start + size)


def claim_domain_block(lock_dir: Path, count: int) -> range:
    """The first of ``count`` blocks of :data:`DOMAIN_IDS` no live process holds, held by this one until it
    ends (a POSIX lock on ``lock_dir/ros-domain-ids-<i>``): a pytest-xdist worker's own, or a crashed
    worker's for the worker that replaces it.

    Raises:
        RuntimeError: Every block is held.
    """
    for index in range(count):
        descriptor = os.open(lock_dir / f"ros-domain-ids-{index}", os.O_WRONLY | os.O_CREAT, 0o600)
        try:
            fcntl.lockf(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(descriptor)
            continue
        _HELD_BLOCKS.append(descriptor)
        return worker_domain_ids(index, count)
    raise RuntimeError(f"all {count} blocks of ROS_DOMAIN_IDs are held by live processes ({lock_dir})")


def release_domain_blocks() -> None:
    """Lets the blocks this process claimed go (a worker that stops, for its replacement)."""
    while _HELD_BLOCKS:
        os.close(_HELD_BLOCKS.pop())


@contextlib.contextmanager
def private_context(domain_id: int) -> Iterator[Any]:
    """An initialised rclpy Context of its own on ``domain_id``, shut down on exit."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield context
    finally:
        context.try_shutdown()


def spin_until(executor: Any, predicate: Callable[[], bool], timeout_s: float, poll_s: float = 0.01) -> bool:
    """Spin ``executor`` until ``predicate()`` holds; False if ``timeout_s`` passes first."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        executor.spin_once(timeout_sec=poll_s)
    return predicate()


class MessageCollector:
    """Subscribe to one topic in a private context and keep every message received."""

    def __init__(self, context: Any, topic: str, msg_type: type, qos: Any = 10, node_name: str = "collector"):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        self.messages: list[Any] = []
        self.node = rclpy.create_node(node_name, context=context)
        self.node.create_subscription(msg_type, topic, self.messages.append, qos)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)

    def wait_for(self, count: int, timeout_s: float) -> list[Any]:
        """Spin until ``count`` messages arrived (or the timeout passed); return all received."""
        spin_until(self.executor, lambda: len(self.messages) >= count, timeout_s)
        return self.messages

    def close(self) -> None:
        """Remove the node and the executor."""
        self.executor.shutdown()
        self.node.destroy_node()


def topic_names(node: Any) -> set[str]:
    """Names of the topics the graph currently knows, as seen by ``node``."""
    return {name for name, _ in node.get_topic_names_and_types()}


def wait_for_topics(context: Any, names: Sequence[str], timeout_s: float) -> set[str]:
    """Wait until every topic in ``names`` (fully qualified) has a publisher or subscriber in the graph.

    Returns:
        The topics seen when the wait ended; the caller asserts on them (missing ones time out).
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    node = rclpy.create_node("topic_waiter", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        spin_until(executor, lambda: set(names) <= topic_names(node), timeout_s)
        return topic_names(node)
    finally:
        executor.shutdown()
        node.destroy_node()


@dataclass
class NodeProcess:
    """One started OS process with its log files."""

    name: str
    popen: subprocess.Popen[bytes]
    stdout_path: Path
    stderr_path: Path

    def alive(self) -> bool:
        """True while the process runs."""
        return self.popen.poll() is None

    def wait(self, timeout_s: float) -> int:
        """The exit code; still running after ``timeout_s`` (s): aborted, failing with its threads' stacks."""
        try:
            return self.popen.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.popen.pid, signal.SIGABRT)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.popen.wait(timeout=10.0)
            raise AssertionError(
                f"{self.name} still running {timeout_s:g} s later; aborted, its threads:\n{self.logs()}"
            ) from None

    def logs(self) -> str:
        """stdout and stderr so far, for failure messages."""
        out = self.stdout_path.read_text(errors="replace") if self.stdout_path.exists() else ""
        err = self.stderr_path.read_text(errors="replace") if self.stderr_path.exists() else ""
        return f"--- {self.name} stdout ---\n{out}\n--- {self.name} stderr ---\n{err}"


@dataclass
class ProcessGroup:
    """Processes started by one test; ``stop_all`` interrupts, then terminates, then kills and reaps them."""

    log_dir: Path
    processes: list[NodeProcess] = field(default_factory=list)

    def start(self, name: str, argv: Sequence[str], env: dict[str, str] | None = None) -> NodeProcess:
        """Start ``argv`` with the test's environment (plus ``env``), logging to ``log_dir/name.*``."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        full_env = dict(os.environ)
        full_env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        full_env["PYTHONUNBUFFERED"] = "1"
        full_env["PYTHONFAULTHANDLER"] = "1"  # a stuck process shows its threads when aborted
        if env:
            full_env.update(env)
        stdout_path = self.log_dir / f"{name}.out"
        stderr_path = self.log_dir / f"{name}.err"
        with stdout_path.open("wb") as out, stderr_path.open("wb") as err:
            popen = subprocess.Popen(
                list(argv),
                stdout=out,
                stderr=err,
                stdin=subprocess.DEVNULL,
                env=full_env,
                start_new_session=True,
            )
        process = NodeProcess(name, popen, stdout_path, stderr_path)
        self.processes.append(process)
        return process

    def assert_all_alive(self) -> None:
        """Raise AssertionError with the logs of any process that has exited."""
        dead = [p for p in self.processes if not p.alive()]
        if dead:
            details = "\n".join(f"{p.name} exited with {p.popen.returncode}\n{p.logs()}" for p in dead)
            raise AssertionError(f"node processes died:\n{details}")

    def stop(self, process: NodeProcess, timeout_s: float = STOP_TIMEOUT_S) -> int:
        """SIGINT the process group, then SIGTERM, then SIGKILL; return the exit code."""
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if not process.alive():
                break
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.popen.pid, sig)
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.popen.wait(timeout=timeout_s)
        return process.popen.wait()

    def stop_all(self) -> None:
        """Stop and reap every process of the group, newest first."""
        for process in reversed(self.processes):
            self.stop(process)


def run_side_by_side(commands: Sequence[Sequence[str]], timeout_s: float) -> list[tuple[int, str, str]]:
    """Run commands that should end on their own at once; (exit code, stdout, stderr) of each.

    One still running after ``timeout_s`` (s) is killed and the test fails with its output.
    """
    import pytest

    started = [
        subprocess.Popen(c, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for c in commands
    ]
    results = []
    for process in started:
        try:
            out, err = process.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            process.kill()
            out, err = process.communicate()
            pytest.fail(f"{process.args} still running after {timeout_s:g} s:\n{out}\n{err}")
        results.append((process.returncode, out, err))
    return results
