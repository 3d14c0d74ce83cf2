"""smm-launch --plant hardware: the emulator and either loop, real time, to its end; recorded and re-run.

Real processes against the board-clocked emulator at 100 Hz (a loaded two-core machine keeps up). Timings are
printed by smm-launch's closing line, never asserted.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def launch_hardware(ros_processes: Any, tmp_path: Path, name: str, *options: str) -> str:
    """Run ``smm-launch --plant hardware`` case1 PID at 100 Hz with ``options``; its logs (asserts exit 0)."""
    params = tmp_path / "td.yaml"
    # 100 Hz, as the simulator's real-time e2e test: a loaded two-core machine answers most measurements
    params.write_text("/**:\n  ros__parameters:\n    td:\n      filter_factor: [0.01, 0.01]\n")
    launcher = ros_processes.start(
        name,
        [
            sys.executable,
            "-m",
            "smm_bringup.launcher",
            "--plant",
            "hardware",
            "--clock-mode",
            "realtime",
            "--scenario",
            "case1",
            "--algorithm",
            "pid",
            "--control-period",
            "0.01",
            "--params-file",
            str(params),
            *options,
        ],
    )
    try:
        code = launcher.popen.wait(timeout=180)
    except subprocess.TimeoutExpired:
        pytest.fail(f"smm-launch did not finish\n{launcher.logs()}")
    logs: str = launcher.logs()
    assert code == 0, logs
    assert "smm_bench_emulator completed its run" in logs
    return logs


def test_hardware_graph_runs_for_its_duration_and_the_output_goes_live(
    ros_processes: Any, tmp_path: Path
) -> None:
    logs = launch_hardware(ros_processes, tmp_path, "smm-launch-hardware", "--duration", "4")
    summary = next(line for line in logs.splitlines() if line.startswith('{"session"'))
    figures = json.loads(summary)
    assert figures["ticks"] == 400  # 4 s of board time at 100 Hz
    assert figures["applied"] > 0, logs  # the bridge armed and the controller's commands reached the valves
    assert figures["crc_errors"] == 0
    late, enabled = figures["late_commands"], figures["enabled_ticks"]
    closing = (
        f"board: late {late} of {enabled} enabled ticks ({100 * late / enabled:.2f} %), feedback->command"
    )
    assert closing in logs  # the closing line is the emulator's own counters


def _smm_bag(*arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "smm_bag.cli", *arguments],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )


@pytest.mark.parametrize("loop", ["topics", "direct"])
def test_a_recorded_run_of_either_loop_is_analysed_and_re_run(
    ros_processes: Any, tmp_path: Path, loop: str
) -> None:
    bag = tmp_path / "bag"
    options = ("--loop", loop, "--duration", "3", "--record", str(bag))
    logs = launch_hardware(ros_processes, tmp_path, f"smm-launch-{loop}", *options)
    closing = [line for line in logs.splitlines() if "[smm-launch] board: late " in line]
    assert len(closing) == 1, logs
    print(f"\n{loop}: {closing[0]}")
    if loop == "direct":
        assert "[direct_loop] host: late" in logs
    analysed = _smm_bag("analyze", "--json", "--quiet", str(bag))
    assert analysed.returncode == 0, analysed.stdout + analysed.stderr
    assert json.loads(analysed.stdout), analysed.stdout
    rerun = _smm_bag("rerun", "--json", str(bag))
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    summary = json.loads(rerun.stdout)
    assert summary["algorithm"] == "pid" and summary["steps"] > 100  # 3 s at 100 Hz, once armed
    print(f"{loop}: rerun max |offline - recorded| = {summary['command_max_abs_difference_Nm']} N m")
    assert max(summary["command_max_abs_difference_Nm"]) == 0.0  # the same chain on the same inputs
