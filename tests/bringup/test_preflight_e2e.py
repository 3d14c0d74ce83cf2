"""The preflight in a hardware run: a refusal exits 4 with its reason, --force arms with a warning, lockstep
skips it.

The refusal is made certain by ``preflight.added_latency_us`` (10 ms on every rehearsed answer: late at every
candidate rate), never by the machine's speed; no test here asserts how timely the loop was.
"""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

UNDER_SCHED_FIFO = pytest.mark.xdist_group("sched_fifo")
"""A hardware graph in real time: the loop under SCHED_FIFO (the launcher's default priorities, as root) and
/dev/cpu_dma_latency held; make test's two workers never run two of them at once."""

SLOWER = "/**/hw_bridge_node:\n  ros__parameters:\n    preflight.added_latency_us: 10000.0\n"
"""A parameter file that makes every rehearsed answer 10 ms late (the 250 Hz period is 4 ms)."""


def _launch(ros_processes: Any, tmp_path: Path, name: str, *arguments: str) -> tuple[int, str]:
    slower = tmp_path / "slower.yaml"
    slower.write_text(SLOWER)
    argv = [sys.executable, "-m", "smm_bringup.launcher", "--plant", "hardware", "--scenario", "case1"]
    launcher = ros_processes.start(name, [*argv, "--params-file", str(slower), *arguments])
    try:
        code = launcher.popen.wait(timeout=300)
    except subprocess.TimeoutExpired:
        pytest.fail(f"smm-launch did not finish\n{launcher.logs()}")
    return code, launcher.logs()


@UNDER_SCHED_FIFO
def test_a_refused_preflight_exits_4_with_its_figures_and_reason(ros_processes: Any, tmp_path: Path) -> None:
    from smm_hw_bridge.preflight import EXIT_PREFLIGHT_REFUSED

    code, logs = _launch(
        ros_processes, tmp_path, "refused", "--clock-mode", "realtime", "--preflight", "1", "--duration", "1",
        "--start-timeout", "30",
    )  # fmt: skip
    assert code == EXIT_PREFLIGHT_REFUSED, logs
    assert "preflight: rehearsed the loop with output disabled (safe frames) at 1000 Hz control" in logs
    assert "preflight: feedback->command" in logs and "preflight: wake-up" in logs
    assert "preflight: idle states: CPU wake-up latency " in logs  # the setting, whatever it is here
    assert "[smm-launch] idle states: holding " in logs or "[smm-launch] idle states: cannot hold " in logs
    refused = "direct_loop: refused to arm at preflight: this host does not hold 1000 Hz control: 100.00 %"
    assert refused in logs
    assert "none of the candidate rates holds (1000, 500, 250, 200, 100 Hz)" in logs
    assert "the direct loop (--loop direct)" not in logs  # it is the direct loop
    assert "[smm-launch] run: refused to arm at preflight" in logs
    assert "arming" not in logs


@UNDER_SCHED_FIFO
def test_the_topics_loop_rehearses_with_its_controller_and_refuses_too(
    ros_processes: Any, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    from smm_bringup.graph import build_graph
    from smm_bringup.graph_nodes import HW_NODE
    from smm_bringup.graph_options import GraphOptions
    from smm_bringup.supervisor import launch_processes
    from smm_hw_bridge.preflight import EXIT_PREFLIGHT_REFUSED

    options = GraphOptions(
        plant="hardware", clock_mode="realtime", loop="topics", scenario="case1", preflight=1.0, duration=1.0
    )
    slower = ("preflight.added_latency_us", 10000.0)
    specs = [
        dataclasses.replace(spec, parameters=(*spec.parameters, slower)) if spec.name == HW_NODE else spec
        for spec in build_graph(options)
    ]
    assert launch_processes(specs, stop_grace_s=5.0) == EXIT_PREFLIGHT_REFUSED
    logs = "".join(capfd.readouterr())
    refused = "hw_bridge_node: refused to arm at preflight: this host does not hold 1000 Hz control: 100.00 %"
    assert refused in logs
    assert "the direct loop (--loop direct)" in logs
    assert "hw_bridge_node refused to arm at preflight; stopping the graph" in logs


@UNDER_SCHED_FIFO
def test_force_arms_anyway_with_a_warning(ros_processes: Any, tmp_path: Path) -> None:
    code, logs = _launch(
        ros_processes, tmp_path, "forced", "--clock-mode", "realtime", "--preflight", "1", "--force",
        "--duration", "1", "--start-timeout", "30",
    )  # fmt: skip
    assert "preflight: ARMING ANYWAY (preflight.force): this host does not hold 1000 Hz control" in logs
    assert "refused to arm" not in logs
    assert code in (0, 3), logs  # armed: controlled or not is this machine's load, not asserted
    assert "run: " in logs and "the bridge never armed" not in logs


def test_lockstep_skips_the_preflight(ros_processes: Any, tmp_path: Path) -> None:
    code, logs = _launch(ros_processes, tmp_path, "lockstep", "--clock-mode", "lockstep", "--duration", "1")
    assert code == 0, logs
    assert "preflight: skipped (lockstep)" in logs
    assert "preflight: rehearsed" not in logs
