"""The bridge drives a CANopen bench it was not written with (tests/hw_bridge/independent_bench), through its
parameters alone: ``smm-launch --link canopen --board external --params-file``. Lockstep: its tracking against
the emulated bench's (a run the bridge ends after ``--duration``), and a kill mid-run; real time: the kill
only (its tracking depends on the machine's speed: bench/bench_independent_realtime.py measures it)."""

from __future__ import annotations

import signal
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from hw_bridge.independent_bench.parameters import bench_parameters
from launcher_run import analyze

pytestmark = [pytest.mark.ros, pytest.mark.slow]

HERE = Path(__file__).resolve().parent / "independent_bench"
GROUP, PORT = "239.74.163.9", 43131
DURATION_S = 2.0


def _start_bench(ros_processes: Any, tmp_path: Path, duration_s: float, *options: str) -> tuple[Any, Path]:
    status = tmp_path / "independent.json"
    bench = ros_processes.start(
        "independent-bench",
        [sys.executable, str(HERE / "run.py"), GROUP, str(PORT), str(duration_s), str(status), *options],
    )
    return bench, status


def _launch(ros_processes: Any, name: str, *options: str, clock_mode: str = "lockstep") -> Any:
    base = ["--plant", "hardware", "--link", "canopen", "--clock-mode", clock_mode, "--scenario", "case2"]
    return ros_processes.start(name, [sys.executable, "-m", "smm_bringup.launcher", *base, *options])


def _wait_for(predicate: Any, what: str, process: Any, timeout_s: float = 1800.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline or not process.alive():
            pytest.fail(f"{what} not seen\n{process.logs()}")
        time.sleep(0.5)


def _rms(bag: Path) -> tuple[float, float]:
    figures = analyze(bag)["case2"]["fpdeso"]
    return figures["alpha"]["RMS"], figures["beta"]["RMS"]


def test_lockstep_case2_on_the_independent_bench_tracks_as_on_the_emulated_one(
    ros_processes: Any, tmp_path: Path
) -> None:
    params = bench_parameters(tmp_path / "bench.yaml", GROUP, PORT)
    bench, _ = _start_bench(ros_processes, tmp_path, DURATION_S + 1.0)  # it runs on past the run's end
    launcher = _launch(
        ros_processes,
        "smm-launch-independent",
        "--board",
        "external",
        "--params-file",
        str(params),
        "--duration",  # nothing else ends an external bench's run: the bridge ends it after 2 s live
        str(DURATION_S),
        "--record",
        str(tmp_path / "independent"),
    )
    code = launcher.wait(1800.0)
    logs = launcher.logs()
    assert code == 0, logs
    assert f"autostart: the planned {DURATION_S:g} s live are done: output disabled, the run ends" in logs, (
        logs
    )
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


@pytest.mark.parametrize("planned", [False, True], ids=["until-stopped", "planned"])
def test_the_independent_bench_killed_mid_run_faults_the_bridge_naming_the_node(
    ros_processes: Any, tmp_path: Path, planned: bool
) -> None:
    """Without a planned length the faulted run waits for a person; with one it ends at once (exit 3): it
    cannot reach its plan, and nothing re-arms it."""
    params = bench_parameters(tmp_path / "bench.yaml", GROUP, PORT)
    bench, _ = _start_bench(ros_processes, tmp_path, 0.0)
    plan = ["--duration", "3600"] if planned else []
    launcher = _launch(
        ros_processes, "smm-launch-killed", "--board", "external", "--params-file", str(params), *plan
    )
    _wait_for(
        lambda: "configured: encoder beta (node 32)" in launcher.logs(), "the configured bench", launcher
    )
    time.sleep(3.0)  # mid-run
    bench.popen.send_signal(signal.SIGKILL)
    _wait_for(lambda: "error transition" in launcher.logs(), "the bridge's fault", launcher, 120.0)
    if planned:
        code = launcher.wait(120.0)
        logs = launcher.logs()
        assert code == 3, logs
        assert "the run ends at its fault, before its planned 3600 s live" in logs, logs
        assert "hw_bridge_node: the run did not control (exit code 3" in logs, logs
    else:
        time.sleep(2.0)
        assert launcher.alive(), launcher.logs()  # waits for a person: the operator ends it
        launcher.popen.send_signal(signal.SIGINT)
        code = launcher.wait(120.0)
    logs = launcher.logs()
    assert code != 0, logs
    fault = next(line for line in logs.splitlines() if "safe output, error transition" in line)
    assert "heartbeat lost (none for 3000 ms)" in fault and "(node 2" in fault, logs
    assert "hw_bridge_node: the run did not control: it faulted: board fault bits" in logs, logs
    assert "Traceback" not in logs, logs


def test_the_independent_bench_killed_mid_run_in_real_time_faults_the_bridge_naming_the_node(
    ros_processes: Any, tmp_path: Path
) -> None:
    """Real time at the default rate, the bridge the SYNC clock. Nothing here depends on this machine's speed:
    ``--force`` arms whatever the preflight measured, and the limits a slow host's late periods could trip
    first (the bridge's link and host watchdogs, TPDO validity, the valves' receive deadline) are generous or
    off, so the fault is the kill's: the nodes' heartbeats lost (3 x 1000 ms)."""
    params = bench_parameters(
        tmp_path / "bench.yaml",
        GROUP,
        PORT,
        heartbeat_ms=1000,
        pdo_validity_ms=60_000,
        **{
            "bridge.host_watchdog_ns": 10_000_000_000,
            "bridge.link_timeout_ns": 60_000_000_000,
            "bridge.admission.stale_ns": 60_000_000_000,
        },
    )
    bench, _ = _start_bench(ros_processes, tmp_path, 0.0, "--no-receive-deadline")
    launcher = _launch(
        ros_processes,
        "smm-launch-realtime-killed",
        "--board",
        "external",
        "--params-file",
        str(params),
        "--force",
        clock_mode="realtime",
    )
    _wait_for(lambda: "; arming" in launcher.logs() or "ARMING ANYWAY" in launcher.logs(), "arming", launcher)
    time.sleep(2.0)  # mid-run
    assert "error transition" not in launcher.logs(), launcher.logs()
    bench.popen.send_signal(signal.SIGKILL)
    _wait_for(lambda: "error transition" in launcher.logs(), "the bridge's fault", launcher, 120.0)
    if launcher.alive():
        launcher.popen.send_signal(signal.SIGINT)
    code = launcher.wait(120.0)
    logs = launcher.logs()
    assert code != 0, logs
    fault = next(line for line in logs.splitlines() if "safe output, error transition" in line)
    assert "heartbeat lost (none for 3000 ms)" in fault, logs
    assert any(f"(node {node})" in fault for node in (21, 22, 31, 32)), logs
    # its verdict: the fault, or first the late periods a slow machine had before it (both "did not control")
    assert "the run did not control: " in logs, logs
    assert "Traceback" not in logs, logs
