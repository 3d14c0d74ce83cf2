"""smm-launch --plant hardware: the emulator and either loop to its end; recorded and re-run; runs that do not
control exit 3.

Lockstep (the emulator clocked by the controller's answers over the same UDP protocol) in ``make test``; the
same tests in real time (250 Hz control, the board at 1 kHz) need a quiet machine (``make test-realtime``: a
run more than 1 % late exits 3). Timings are printed by smm-launch's closing lines, never asserted.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]


CLOCK_MODES = [pytest.param("lockstep"), pytest.param("realtime", marks=pytest.mark.realtime)]


def launch_hardware(ros_processes: Any, tmp_path: Path, name: str, clock_mode: str, *options: str) -> str:
    """Run ``smm-launch --plant hardware`` case1 PID at 250 Hz with ``options``; its logs (asserts exit 0)."""
    params = tmp_path / "td.yaml"
    # 250 Hz, as the simulator's real-time e2e test: a loaded two-core machine answers most measurements
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
            clock_mode,
            "--scenario",
            "case1",
            "--algorithm",
            "pid",
            "--control-rate",
            "250",
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
    assert "[smm-launch] run: controlled (late " in logs
    return logs


@pytest.mark.parametrize("clock_mode", CLOCK_MODES)
def test_hardware_graph_runs_for_its_duration_and_the_output_goes_live(
    ros_processes: Any, tmp_path: Path, clock_mode: str
) -> None:
    logs = launch_hardware(ros_processes, tmp_path, "smm-launch-hardware", clock_mode, "--duration", "4")
    summary = next(line for line in logs.splitlines() if line.startswith('{"session"'))
    figures = json.loads(summary)
    assert figures["ticks"] == 4000  # 4 s of board time at its 1 kHz tick
    assert figures["applied"] > 0, logs  # the bridge armed and the controller's commands reached the valves
    # about one command per 4 ticks (a lockstep re-send is latched once more): the board held the others
    assert figures["applied"] < figures["ticks"] / 2 and figures["control_divider"] == 4
    if clock_mode == "lockstep":  # every period waits for its answer: none is late, though the board holds
        assert figures["late_periods"] == 0 and figures["judged_periods"] > 0, logs
    assert figures["crc_errors"] == 0
    late, enabled = figures["late_commands"], figures["enabled_ticks"]
    closing = (
        f"board: late {late} of {enabled} enabled ticks ({100 * late / enabled:.2f} %) (its count per tick: "
        "it holds 3 of every 4), feedback->command"
    )
    assert closing in logs  # the closing line is the emulator's own counters
    # the bridge counts the same ticks from the feedback frames it admitted
    assert (
        f"[hw_bridge_node] host: {figures['figures']}, from the board's feedback frames; controlled" in logs
    )


def _smm_bag(*arguments: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "smm_bag.cli", *arguments],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )


@pytest.mark.parametrize("clock_mode", CLOCK_MODES)
@pytest.mark.parametrize("loop", ["topics", "direct"])
def test_a_recorded_run_of_either_loop_is_analysed_and_re_run(
    ros_processes: Any, tmp_path: Path, loop: str, clock_mode: str
) -> None:
    bag = tmp_path / "bag"
    options = ("--loop", loop, "--duration", "3", "--record", str(bag))
    logs = launch_hardware(ros_processes, tmp_path, f"smm-launch-{loop}", clock_mode, *options)
    closing = [line for line in logs.splitlines() if "[smm-launch] board: late " in line]
    assert len(closing) == 1, logs
    print(f"\n{loop}: {closing[0]}")
    bridge = "direct_loop" if loop == "direct" else "hw_bridge_node"
    host = next(line for line in logs.splitlines() if line.startswith(f"[{bridge}] host: late "))
    assert "; controlled" in host and "live ticks" in host, logs
    from smm_bag.metadata import read_metadata

    assert read_metadata(bag).custom_data["smm.seed"] == "0"  # the emulator's default seed, no --seed
    analysed = _smm_bag("analyze", "--json", "--quiet", str(bag))
    assert analysed.returncode == 0, analysed.stdout + analysed.stderr
    assert json.loads(analysed.stdout), analysed.stdout
    rerun = _smm_bag("rerun", "--json", str(bag))
    assert rerun.returncode == 0, rerun.stdout + rerun.stderr
    summary = json.loads(rerun.stdout)
    assert summary["algorithm"] == "pid" and summary["steps"] > 100  # 3 s at 100 Hz, once armed
    print(f"{loop}: rerun max |offline - recorded| = {summary['command_max_abs_difference_Nm']} N m")
    assert max(summary["command_max_abs_difference_Nm"]) == 0.0  # the same chain on the same inputs
