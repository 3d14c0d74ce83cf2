"""smm-launch --plant hardware: emulator + hw_bridge_node + the controller graph, real time, to its end."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_hardware_graph_runs_for_its_duration_and_the_output_goes_live(
    ros_processes: Any, tmp_path: Path
) -> None:
    params = tmp_path / "td.yaml"
    # 100 Hz, as the simulator's real-time e2e test: a loaded two-core machine answers most measurements
    params.write_text("/**:\n  ros__parameters:\n    td:\n      filter_factor: [0.01, 0.01]\n")
    launcher = ros_processes.start(
        "smm-launch-hardware",
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
            "--duration",
            "4",
            "--params-file",
            str(params),
        ],
    )
    try:
        code = launcher.popen.wait(timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail(f"smm-launch did not finish\n{launcher.logs()}")
    logs = launcher.logs()
    assert code == 0, logs
    assert "smm_bench_emulator completed its run" in logs
    summary = next(line for line in logs.splitlines() if line.startswith('{"session"'))
    import json

    figures = json.loads(summary)
    assert figures["ticks"] == 400  # 4 s of board time at 100 Hz
    assert figures["applied"] > 0, logs  # the bridge armed and the controller's commands reached the valves
    assert figures["crc_errors"] == 0
