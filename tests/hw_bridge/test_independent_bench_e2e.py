"""The bridge drives a CANopen bench it was not written with (tests/hw_bridge/independent_bench), through its
parameters alone: ``smm-launch --link canopen --board external --params-file``. Lockstep only: a real-time run
at the default CANopen rate waits for the SYNC clock (docs/HW_CANOPEN.md, "An independent bench")."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.slow]

HERE = Path(__file__).resolve().parent / "independent_bench"
GROUP, PORT = "239.74.163.9", 43131
CANOPEN = "canopen"
"""The prefix of the CANopen link's bridge parameters: written once here."""
DURATION_S = 2.0


def _nested(flat: dict[str, Any]) -> dict[str, Any]:
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        *parents, leaf = name.split(".")
        node = tree
        for parent in parents:
            node = node.setdefault(parent, {})
        node[leaf] = value
    return tree


def _yaml(tree: dict[str, Any], indent: int = 0) -> str:
    lines = []
    for key, value in tree.items():
        if isinstance(value, dict):
            lines.append(" " * indent + f"{key}:\n" + _yaml(value, indent + 2))
        else:
            lines.append(" " * indent + f"{key}: {json.dumps(value)}\n")
    return "".join(lines)


def bench_parameters(path: Path, **changes: Any) -> Path:
    """The bridge's parameter file for the independent bench (its node ids, EDS files, units), at ``path``."""
    flat: dict[str, Any] = {
        "link.transport": "canopen",
        f"{CANOPEN}.channel": GROUP,
        f"{CANOPEN}.port": PORT,
        f"{CANOPEN}.valve_node_ids": [21, 22],
        f"{CANOPEN}.encoder_node_ids": [31, 32],
        f"{CANOPEN}.valve_eds": str(HERE / "valve.eds"),
        f"{CANOPEN}.encoder_eds": str(HERE / "encoder.eds"),
        "bridge.valve.gain": [16384 / 12.0, 16384 / 12.0],  # +-16384 = +-100 % = +-12 N m on this bench
        "bridge.valve.code_limit": [16384, 16384],
        "bridge.valve.rate_limit": [16384 / 0.002, 16384 / 0.002],
        "bridge.valve.time_constants": [0.0, 0.0],  # 0x6301 is the spool measured: no lag model on top
        "bridge.encoder.counts_per_rev": [1 << 19, 1 << 19],
        "bridge.encoder.zero_offset": [100_000, 7],
        "bridge.encoder.direction": [1, -1],
    }
    flat.update(
        {f"{CANOPEN}.{k}" if not k.startswith(("bridge.", "link.")) else k: v for k, v in changes.items()}
    )
    path.write_text(_yaml({"/smm/hw_bridge_node": {"ros__parameters": _nested(flat)}}))
    return path


def _start_bench(ros_processes: Any, tmp_path: Path, duration_s: float) -> tuple[Any, Path]:
    status = tmp_path / "independent.json"
    bench = ros_processes.start(
        "independent-bench",
        [sys.executable, str(HERE / "run.py"), GROUP, str(PORT), str(duration_s), str(status)],
    )
    return bench, status


def _launch(ros_processes: Any, name: str, *options: str) -> Any:
    base = ["--plant", "hardware", "--link", "canopen", "--clock-mode", "lockstep", "--scenario", "case2"]
    return ros_processes.start(name, [sys.executable, "-m", "smm_bringup.launcher", *base, *options])


def _wait_for(predicate: Any, what: str, process: Any, timeout_s: float = 1800.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline or not process.alive():
            pytest.fail(f"{what} not seen\n{process.logs()}")
        time.sleep(0.5)


def _rms(bag: Path) -> tuple[float, float]:
    analysed = subprocess.run(
        [sys.executable, "-m", "smm_bag.cli", "analyze", "--json", "--quiet", str(bag)],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert analysed.returncode == 0, analysed.stdout + analysed.stderr
    figures = json.loads(analysed.stdout)["case2"]["fpdeso"]
    return figures["alpha"]["RMS"], figures["beta"]["RMS"]


def test_lockstep_case2_on_the_independent_bench_tracks_as_on_the_emulated_one(
    ros_processes: Any, tmp_path: Path
) -> None:
    params = bench_parameters(tmp_path / "bench.yaml")
    bench, status = _start_bench(ros_processes, tmp_path, DURATION_S)
    launcher = _launch(
        ros_processes,
        "smm-launch-independent",
        "--board",
        "external",
        "--params-file",
        str(params),
        "--record",
        str(tmp_path / "independent"),
    )
    _wait_for(status.exists, "the bench's duration", launcher)
    time.sleep(2.0)  # the bench fell silent: the lockstep run halts; its last messages reach the recorder
    launcher.popen.send_signal(signal.SIGINT)  # an external bench's run ends as a person ends it
    code = launcher.wait(120.0)
    logs = launcher.logs()
    assert code == 128 + signal.SIGINT, logs
    for name, kind in (
        ("valve alpha (node 21): device type 0x00010198", 408),
        ("valve beta (node 22): device type 0x00010198", 408),
        ("encoder alpha (node 31): device type 0x00020196", 406),
        ("encoder beta (node 32): device type 0x00020196", 406),
    ):
        assert f"configured: {name} (CiA {kind}), vendor 0x00A5C0DE" in logs, logs
    host = [line for line in logs.splitlines() if "[hw_bridge_node] host: " in line]
    assert len(host) == 1 and host[0].endswith("; controlled"), logs
    assert "hw_bridge_node: the run did not control" not in logs and "did not stop cleanly" not in logs, logs
    assert "Traceback" not in logs and "Traceback" not in bench.logs(), logs + bench.logs()
    independent = _rms(tmp_path / "independent")

    emulated_run = _launch(
        ros_processes,
        "smm-launch-emulated",
        "--duration",
        str(DURATION_S),
        "--record",
        str(tmp_path / "emulated"),
    )
    assert emulated_run.wait(1800.0) == 0, emulated_run.logs()
    emulated = _rms(tmp_path / "emulated")
    print(f"\ntracking RMS (rad) alpha, beta: independent bench {independent}, emulated bench {emulated}")
    assert all(mine <= 1.1 * theirs for mine, theirs in zip(independent, emulated, strict=True))


def test_the_independent_bench_killed_mid_run_faults_the_bridge_naming_the_node(
    ros_processes: Any, tmp_path: Path
) -> None:
    params = bench_parameters(tmp_path / "bench.yaml")
    bench, _ = _start_bench(ros_processes, tmp_path, 0.0)
    launcher = _launch(
        ros_processes, "smm-launch-killed", "--board", "external", "--params-file", str(params)
    )
    _wait_for(
        lambda: "configured: encoder beta (node 32)" in launcher.logs(), "the configured bench", launcher
    )
    time.sleep(3.0)  # mid-run
    bench.popen.send_signal(signal.SIGKILL)
    _wait_for(lambda: "error transition" in launcher.logs(), "the bridge's fault", launcher, 120.0)
    launcher.popen.send_signal(signal.SIGINT)
    code = launcher.wait(120.0)
    logs = launcher.logs()
    assert code != 0, logs
    fault = next(line for line in logs.splitlines() if "safe output, error transition" in line)
    assert "heartbeat lost (none for 3000 ms)" in fault and "(node 2" in fault, logs
    assert "hw_bridge_node: the run did not control: it faulted: board fault bits" in logs, logs
    assert "Traceback" not in logs, logs
