"""A hardware run that did not control exits 3 and says why; a lockstep hardware run is deterministic.

Lockstep and "never armed" runs: nothing here depends on the machine keeping up with a clock.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from launcher_run import analyze
from udp_bench import LOOPBACK, free_port

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _launch(ros_processes: Any, name: str, *arguments: str) -> tuple[int, str]:
    launcher = ros_processes.start(name, [sys.executable, "-m", "smm_bringup.launcher", *arguments])
    try:
        code = launcher.popen.wait(timeout=600)
    except subprocess.TimeoutExpired:
        pytest.fail(f"smm-launch did not finish\n{launcher.logs()}")
    return code, launcher.logs()


def test_hardware_lockstep_case2_recorded_twice_gives_a_bag_with_the_same_indices(
    ros_processes: Any, tmp_path: Path
) -> None:
    indices = []
    for run in (1, 2):
        bag = tmp_path / f"case2-{run}"
        arguments = (
            "--plant",
            "hardware",
            "--clock-mode",
            "lockstep",
            "--scenario",
            "case2",
            "--record",
            str(bag),
        )
        code, logs = _launch(ros_processes, f"smm-launch-{run}", *arguments)
        assert code == 0, logs
        assert "[smm-launch] run: controlled (late 0 of 3999 periods of 1 ms after the first 1 s live" in logs
        assert " 0 lost, 0 samples missing in stamps" in logs  # else the indices differ for want of samples
        indices.append(analyze(bag))
    assert indices[0]["case2"] == indices[1]["case2"]
    assert indices[0]["case2"]["fpdeso"]["alpha"]["RMS"] < 0.05  # rad: it tracked the reference


def test_a_lockstep_hardware_run_that_never_starts_exits_3_and_says_why(tmp_path: Path) -> None:
    from smm_bringup.graph import build_graph
    from smm_bringup.graph_nodes import CONTROLLER_NODE
    from smm_bringup.graph_options import GraphOptions
    from smm_bringup.launcher import verdict_line, with_board_status
    from smm_bringup.supervisor import launch_processes
    from smm_hw_bridge.run_verdict import EXIT_NOT_CONTROLLED

    options = GraphOptions(plant="hardware", clock_mode="lockstep", scenario="case2", start_timeout=2.0)
    # No controller: the bridge waits for a torque_command publisher and the board for its first answer.
    specs = [spec for spec in build_graph(options) if spec.name != CONTROLLER_NODE]
    status = tmp_path / "board.json"
    assert launch_processes(with_board_status(specs, status), stop_grace_s=5.0) == EXIT_NOT_CONTROLLED
    assert verdict_line(status) == (
        "run: did not control: the lockstep run never started: no step within its start timeout of 2 s "
        "(late 0 of 0 periods of 1 ms after the first 1 s live (0.00 %), 0 live ticks in all)"
    )


def test_a_bridge_that_never_arms_exits_3_and_both_sides_say_so(ros_processes: Any) -> None:
    host, board = free_port(), free_port()
    emulator = ros_processes.start(
        "emulator",
        [sys.executable, "-m", "smm_bench_emulator.cli", "--bind", f"{LOOPBACK}:{board}",
         "--host", f"{LOOPBACK}:{host}", "--control", f"{LOOPBACK}:{free_port()}", "--duration", "3"],
    )  # fmt: skip
    bridge = ros_processes.start(
        "hw_bridge_node",
        [sys.executable, "-m", "smm_hw_bridge.bridge_node", "--ros-args", "-r", "__ns:=/smm",
         "-p", "autostart:=true", "-p", f"link.bind_port:={host}", "-p", f"link.board_port:={board}"],
    )  # fmt: skip
    # no controller: autostart waits for a torque_command publisher, so nothing ever arms
    assert emulator.wait(120) == 3, emulator.logs()
    assert "the run did not control: the bridge never armed" in emulator.logs()
    os.killpg(bridge.popen.pid, signal.SIGINT)
    assert bridge.wait(60) == 3, bridge.logs()
    reason = "the bridge never armed: autostart waited for the controller to the end"
    assert f"hw_bridge_node: the run did not control: {reason}" in bridge.logs()
    assert f"[hw_bridge_node] host: no feedback frame counted; did not control: {reason}" in bridge.logs()


@pytest.mark.realtime
def test_a_realtime_run_more_late_than_its_limit_exits_3(ros_processes: Any) -> None:
    # A limit of 0 %: one held tick in 3 s at 1 kHz through DDS is enough (the quiet developers' machine
    # holds about 0.1 % with the topics loop, docs/LAUNCH.md); no preflight, which would refuse to arm.
    arguments = ("--plant", "hardware", "--clock-mode", "realtime", "--scenario", "case1", "--algorithm",
                 "pid", "--duration", "3", "--late-limit", "0", "--loop", "topics",
                 "--preflight", "0")  # fmt: skip
    code, logs = _launch(ros_processes, "smm-launch-late", *arguments)
    assert code == 3, logs
    assert (
        "[smm-launch] run: did not control: " in logs
        and "were late or not live, above the limit of 0 %" in logs
    )


@pytest.mark.parametrize("composed", [False, True])
def test_a_realtime_simulator_run_that_did_not_control_exits_3_as_the_hardware_path(
    ros_domain_id: int, composed: bool, capfd: pytest.CaptureFixture[str]
) -> None:
    """No controller (the test's own domain): every tick of the 1 s run applies zero torque, so the run did
    not control on any machine; the supervisor (and composed mode) pass the simulator's exit 3 on."""
    from smm_bringup.composed import launch_composed
    from smm_bringup.graph import build_graph
    from smm_bringup.graph_nodes import CONTROLLER_NODE
    from smm_bringup.graph_options import GraphOptions
    from smm_bringup.supervisor import launch_processes
    from smm_node_runtime.run_verdict import EXIT_NOT_CONTROLLED

    options = GraphOptions(clock_mode="realtime", scenario="case1", duration=1.0)
    specs = [spec for spec in build_graph(options) if spec.name != CONTROLLER_NODE]
    code = launch_composed(specs) if composed else launch_processes(specs, stop_grace_s=5.0)
    assert code == EXIT_NOT_CONTROLLED
    logs = "".join(capfd.readouterr())
    reason = "run: did not control: no torque command reached the plant: all 1000 ticks applied zero torque"
    assert reason in logs, logs
    if not composed:
        assert "smm_sim_node: the run did not control (exit code 3; its reason above)" in logs
