"""smm-launch --plant hardware --link canopen: the emulated CANopen bench and its master, both clock modes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from launcher_run import smm_launch
from smm_bringup.graph_options import GraphOptions

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_lockstep_canopen_run_names_each_node_and_controls(ros_processes: Any) -> None:
    launcher = ros_processes.start(
        "smm-launch-canopen",
        [
            sys.executable,
            "-m",
            "smm_bringup.launcher",
            "--plant",
            "hardware",
            "--link",
            "canopen",
            "--clock-mode",
            "lockstep",
            "--scenario",
            "case2",
            "--duration",
            "1",
        ],
    )
    try:
        code = launcher.popen.wait(timeout=180)
    except subprocess.TimeoutExpired:
        pytest.fail(f"smm-launch did not finish\n{launcher.logs()}")
    logs: str = launcher.logs()
    assert code == 0, logs
    for name, kind in (
        ("valve alpha (node 1)", 408),
        ("valve beta (node 2)", 408),
        ("encoder alpha (node 11)", 406),
        ("encoder beta (node 12)", 406),
    ):
        assert f"configured: {name}: device type " in logs and f"(CiA {kind})" in logs, logs
    assert "[smm-launch] run: controlled (" in logs and "1000 with both valves ACTIVE" in logs, logs


def test_realtime_canopen_run_arms_on_the_sync_clock_controls_and_says_so(
    ros_processes: Any, tmp_path: Path
) -> None:
    """The real-time path, not its timing: late periods are allowed (--late-limit 100), no preflight."""
    generous = tmp_path / "generous.yaml"  # a loaded machine's stall faults no device in this test
    generous.write_text(
        "/**/hw_bridge_node:\n  ros__parameters:\n    canopen:\n"
        "      pdo_validity_ms: 60000\n      heartbeat_ms: 1000\n      receive_deadline_ms: 60000\n"
    )
    arguments = ["--plant", "hardware", "--link", "canopen", "--clock-mode", "realtime"]
    arguments += ["--scenario", "case1", "--duration", "2", "--control-rate", "1000", "--preflight", "0"]
    arguments += ["--late-limit", "100", "--rt-priority", "0", "--params-file", str(generous)]
    code, logs = smm_launch(ros_processes, "smm-launch-canopen-rt", *arguments, timeout=180)
    assert code == 0, logs
    assert "CANopen bench on " in logs and ", realtime" in logs, logs
    assert "[smm-launch] run: controlled (" in logs, logs
    status = json.loads(next(line for line in logs.splitlines() if line.startswith('{"link": "canopen"')))
    assert status["live_ticks"] >= 2000 and status["enabled_ticks"] > 0, logs  # 2 s of 1 ms periods live
    host = [line for line in logs.splitlines() if "host: late " in line]
    assert host and host[-1].split("; ")[1].startswith("controlled"), logs


@pytest.mark.parametrize(
    ("changes", "why"),
    [
        ({"board": "127.0.0.1:50101"}, "board on link 'canopen' is 'external' or none"),
        ({"plant": "sim"}, "needs plant 'hardware'"),
    ],
)
def test_what_the_canopen_link_cannot_do_is_refused(changes: dict[str, Any], why: str) -> None:
    options: dict[str, Any] = {"plant": "hardware", "link": "canopen", **changes}
    with pytest.raises(ValueError, match=why):
        GraphOptions(**options)
