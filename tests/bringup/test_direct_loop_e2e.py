"""smm-launch --plant hardware, both loops, recorded: smm-bag analyses and re-runs either bag the same way.

Real processes against the board-clocked emulator at 100 Hz (a loaded two-core machine keeps up), 3 s
armed. Timings are printed by smm-launch's closing line, never asserted.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _launch(ros_processes: Any, tmp_path: Path, loop: str, bag: Path) -> str:
    params = tmp_path / "td.yaml"
    params.write_text("/**:\n  ros__parameters:\n    td:\n      filter_factor: [0.01, 0.01]\n")
    launcher = ros_processes.start(
        f"smm-launch-{loop}",
        [
            sys.executable,
            "-m",
            "smm_bringup.launcher",
            "--plant",
            "hardware",
            "--clock-mode",
            "realtime",
            "--loop",
            loop,
            "--scenario",
            "case1",
            "--algorithm",
            "pid",
            "--control-period",
            "0.01",
            "--duration",
            "3",
            "--params-file",
            str(params),
            "--record",
            str(bag),
        ],
    )
    try:
        code = launcher.popen.wait(timeout=180)
    except subprocess.TimeoutExpired:
        pytest.fail(f"smm-launch did not finish\n{launcher.logs()}")
    logs: str = launcher.logs()
    assert code == 0, logs
    return logs


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
    logs = _launch(ros_processes, tmp_path, loop, bag)
    closing = [line for line in logs.splitlines() if "[smm-launch] board: late " in line]
    assert len(closing) == 1, logs
    print(f"\n{loop}: {closing[0]}")
    if loop == "direct":
        assert "[direct_loop] host: late" in logs
    analysed = _smm_bag("analyze", "--json", "--quiet", str(bag))
    assert analysed.returncode == 0, analysed.stdout + analysed.stderr
    metrics = json.loads(analysed.stdout)
    assert metrics, analysed.stdout
    rerun = _smm_bag("rerun", "--json", str(bag))
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    summary = json.loads(rerun.stdout)
    assert summary["algorithm"] == "pid" and summary["steps"] > 100  # 3 s at 100 Hz, once armed
    print(f"{loop}: rerun max |offline - recorded| = {summary['command_max_abs_difference_Nm']} N m")
    assert max(summary["command_max_abs_difference_Nm"]) == 0.0  # the same chain on the same inputs
