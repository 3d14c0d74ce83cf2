"""smm-launch --plant hardware --link canopen in lockstep: the emulated CANopen bench and its master."""

from __future__ import annotations

import subprocess
import sys
from typing import Any

import pytest
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


@pytest.mark.parametrize(
    ("changes", "why"),
    [
        ({"clock_mode": "realtime"}, "clock mode 'lockstep'"),
        ({"control_rate": 250.0}, "the 1000 Hz control rate"),
        ({"board": "127.0.0.1:50101"}, "board on link 'canopen' is 'external' or none"),
        ({"plant": "sim"}, "needs plant 'hardware'"),
    ],
)
def test_what_the_canopen_link_cannot_do_yet_is_refused(changes: dict[str, Any], why: str) -> None:
    options: dict[str, Any] = {"plant": "hardware", "link": "canopen", **changes}
    with pytest.raises(ValueError, match=why):
        GraphOptions(**options)
