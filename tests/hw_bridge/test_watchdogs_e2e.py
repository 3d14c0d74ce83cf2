"""kill -9 in the middle of a real-time run (board-clocked emulator at 1 kHz), in both loops.

Controller killed (topics loop): the bridge's host watchdog sends safe output. The process talking to the
board killed (hw_bridge_node in the topics loop, direct_loop in the direct loop): the board's own watchdog
nulls the valves. Wall-clock figures are measured and printed (never asserted); what is asserted is what
the board guarantees on its own clock: the valves are at null by the end of the last command's validity.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import sys
import time
from typing import Any

import pytest
from udp_bench import LOOPBACK, free_port

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.realtime]
"""A loop kept at 1 kHz until the kill (make test-realtime); the twins on the board's and the host watchdog's
own clocks: tests/bench_emulator/test_board.py, tests/hw_bridge/test_core.py (docs/TESTING.md)."""

VALIDITY = 50  # ticks: long enough that the controller-kill case shows the host watchdog, not the board's
HOST_WATCHDOG_MS = 10.0


def status(port: int) -> dict[str, Any]:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(1.0)
        sock.sendto(b'{"status": true}', (LOOPBACK, port))
        try:
            reply: dict[str, Any] = json.loads(sock.recv(65536))
        except (TimeoutError, ConnectionRefusedError):
            return {}  # the emulator is not up yet
        return reply


def wait_for(predicate: Any, timeout_s: float, what: str, group: Any) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if group is not None:
            group.assert_all_alive()
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def start(ros_processes: Any, loop: str = "topics") -> tuple[Any, Any, int]:
    """Emulator, then the loop: bridge + controller_node processes (topics) or one direct_loop (direct).

    Returns:
        (the bridge's process, the controller's process (the same with ``direct``), emulator control port).
    """
    from smm_bringup.graph import build_graph
    from smm_bringup.graph_nodes import CONTROLLER_NODE, HW_NODE
    from smm_bringup.graph_options import GraphOptions

    host, board, control = free_port(), free_port(), free_port()
    ros_processes.start(
        "emulator",
        [
            sys.executable,
            "-m",
            "smm_bench_emulator.cli",
            "--bind",
            f"{LOOPBACK}:{board}",
            "--host",
            f"{LOOPBACK}:{host}",
            "--control",
            f"{LOOPBACK}:{control}",
        ],
    )
    spec = next(
        s
        for s in build_graph(GraphOptions(clock_mode="realtime", scenario="case1", algorithm="pid"))
        if s.name == CONTROLLER_NODE
    )
    bridge_arguments = [
        "-p",
        "autostart:=true",
        "-p",
        f"link.bind_port:={host}",
        "-p",
        f"link.board_port:={board}",
        "-p",
        "link.configure_timeout:=10.0",
        "-p",
        f"bridge.validity_ticks:={VALIDITY}",
        "-p",
        f"bridge.host_watchdog_ns:={int(HOST_WATCHDOG_MS * 1e6)}",
        "-p",
        "preflight.duration_s:=0.0",  # arm at once: the watchdogs are the subject, not this host's timing
    ]
    if loop == "direct":
        # one process: controller_node's arguments (no __node remapping: it hosts two), then the bridge's
        hosted = dataclasses.replace(spec, hosts=(CONTROLLER_NODE, HW_NODE))
        direct = ros_processes.start(
            "direct_loop",
            [sys.executable, "-m", "smm_direct_loop.host", *hosted.ros_arguments(), *bridge_arguments],
        )
        wait_for(
            lambda: status(control).get("applied", 0) > 500, 60.0, "the output to go live", ros_processes
        )
        return direct, direct, control
    bridge = ros_processes.start(
        "hw_bridge_node",
        [
            sys.executable,
            "-m",
            "smm_hw_bridge.bridge_node",
            "--ros-args",
            "-r",
            "__ns:=/smm",
            *bridge_arguments,
        ],
    )
    controller = ros_processes.start(
        "controller_node", [sys.executable, "-m", "smm_controller.controller_node", *spec.ros_arguments()]
    )
    wait_for(lambda: status(control).get("applied", 0) > 500, 60.0, "the output to go live", ros_processes)
    return bridge, controller, control


def settled(control: int) -> dict[str, Any]:
    """The emulator's status once the valves are at null and no enabled command came for 0.3 s."""
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline:
        figures = status(control)
        if figures.get("null_since_ns") is not None and figures.get("last_enabled_ns") is not None:
            quiet_ns = time.monotonic_ns() - figures["last_enabled_ns"]
            if quiet_ns > 300_000_000 and figures["null_since_ns"] >= figures["last_enabled_ns"]:
                return figures
        time.sleep(0.05)
    raise AssertionError(f"the valves did not settle at null: {status(control)}")


def kill9(process: Any) -> None:
    os.killpg(process.popen.pid, signal.SIGKILL)
    process.popen.wait()


def test_kill_controller_host_watchdog_puts_safe_output(ros_processes: Any) -> None:
    _, controller, control = start(ros_processes)
    kill9(controller)
    figures = settled(control)
    assert figures["output_codes"] == [0, 0]
    elapsed_ms = (figures["null_since_ns"] - figures["last_enabled_ns"]) / 1e6
    ticks = figures["null_since_tick"] - figures["last_applied_tick"]
    by = "the board's watchdog" if figures["status_bits"] & 0x0008 else "the host watchdog (safe frame)"
    print(
        f"\nkill -9 controller: valves at null {elapsed_ms:.1f} ms after the last enabled command reached "
        f"the board ({ticks} board ticks; host watchdog {HOST_WATCHDOG_MS:.0f} ms + 2 periods = "
        f"{HOST_WATCHDOG_MS + 2:.0f} ms), by {by}"
    )
    assert 1 <= ticks <= VALIDITY  # whatever the host does, the board's own clock bounds it


@pytest.mark.parametrize("loop", ["topics", "direct"])
def test_kill_the_loop_process_board_watchdog_nulls_the_valves_within_validity(
    ros_processes: Any, loop: str
) -> None:
    """kill -9 of the process that talks to the board: hw_bridge_node (topics) or direct_loop (direct)."""
    bridge, _, control = start(ros_processes, loop)
    kill9(bridge)
    figures = settled(control)
    assert figures["output_codes"] == [0, 0]
    assert figures["status_bits"] & 0x0008, "the board's watchdog bit is not set"
    ticks = figures["null_since_tick"] - figures["last_applied_tick"]
    elapsed_ms = (figures["null_since_ns"] - figures["last_enabled_ns"]) / 1e6
    print(
        f"\nkill -9 {loop} loop's process: valves at null {ticks} board ticks after the last applied command "
        f"(validity {VALIDITY} + 1 tick after the measurement it answered), {elapsed_ms:.1f} ms of wall time "
        f"after the last enabled command reached the board"
    )
    assert 1 <= ticks <= VALIDITY
