"""Benchmark of the hardware path: real-time HIL against the board-clocked emulator, beside the host floor.

Figures, not pass/fail (``make bench``). Every process runs in a private network namespace (re-exec under
``unshare --net``, as bench_graph.py), with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``.

0. The host floor of this run (bench_graph's bare 1 ms sleep loop and bare UDP ping-pong).
1. Lockstep reference: ``smm-launch --clock-mode lockstep`` case1, FPDESO, the same plant as the emulator
   (2^20 counts/rev, 20 N m saturation, no valve lag), 30 s; tracking RMS over whole reference periods.
2. Real-time HIL, separate processes, at 1 kHz (the acceptance rate), then at 100 Hz:
   ``smm_bench_emulator`` (own clock) <- UDP -> ``hw_bridge_node`` <- DDS -> ``controller_node`` (case1,
   FPDESO), 30 s of armed output: late-command fraction on the board's
   clock, feedback-to-command latency p50/p99 seen by the board, tracking RMS and its ratio to step 1
   (target <= 1.5). Beside it, what the offline loop gives with the same plant when every command acts
   one period late (the board applies a command at the tick after the feedback it answers): the part of
   the penalty that is the controller's, not the host's.
   The emulator stands for the board, whose 1 kHz loop is hard real time: it runs under SCHED_FIFO 70
   (as ``smm-launch --plant hardware`` starts it) when the system allows it, so that a loaded host slows
   the stack under test, not the "board". At 1 kHz the HIL runs twice: the bridge and the controller at
   normal priority (a host that refuses SCHED_FIFO), then under SCHED_FIFO 50 (``smm-launch``'s default
   for the hardware plant).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
SECONDS = float(os.environ.get("SMM_BENCH_HIL_SECONDS", "30"))
"""Armed seconds per run; ``SMM_BENCH_HIL_SECONDS=6`` for a short run that shows it works (not the
acceptance's figures)."""
FULL_SCALE = 20.0
COUNTS = 1 << 20
RMS_RATIO_TARGET = 1.5
PERIODS = (1e-3, 1e-2)
"""The acceptance rate (1 kHz), then 100 Hz, where a loaded two-core machine keeps up with three processes."""


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def tracking_rms(
    t: np.ndarray, q: np.ndarray, start: float, seconds: float, origin: float = 0.0
) -> np.ndarray:
    """RMS of case1's tracking error per joint over [start, start + seconds) (rad).

    ``origin``: the controller's time zero (it samples the reference at stamp - its first stamp).
    """
    window = (t >= start) & (t < start + seconds)
    phase = np.pi * (t - origin)
    reference = np.stack([np.sin(phase), 0.785 * np.sin(phase)], axis=1)
    error = reference[window] - q[window]
    return np.asarray(np.sqrt(np.mean(error**2, axis=0)))


def td_yaml(workdir: Path, period: float) -> Path:
    """Every node's period = the board's tick ``period`` here (not a control rate below the tick: the board
    itself ticks at ``period``); the TD's filter factor h must be >= it."""
    path = workdir / f"td_{period}.yaml"
    h = max(period, 0.001)
    path.write_text(
        f"/**:\n  ros__parameters:\n    control_period: {period}\n    td:\n      filter_factor: [{h}, {h}]\n"
    )
    return path


def lockstep_reference(workdir: Path, period: float) -> np.ndarray | None:
    """Tracking RMS of the lockstep simulator run of the same plant (whole reference periods after 2 s)."""
    record = workdir / f"lockstep_{period}.npz"
    params = workdir / f"lockstep_{period}.yaml"
    params.write_text(
        f'/**/smm_sim_node:\n  ros__parameters:\n    record_file: "{record}"\n'
        f"    encoder_counts_per_rev: {COUNTS}\n    torque_limit: [{FULL_SCALE}, {FULL_SCALE}]\n"
    )
    command = [
        sys.executable,
        "-m",
        "smm_bringup.launcher",
        "--clock-mode",
        "lockstep",
        "--scenario",
        "case1",
    ]
    command += ["--duration", str(SECONDS)]
    command += ["--params-file", str(td_yaml(workdir, period)), "--params-file", str(params)]
    log = workdir / f"lockstep_{period}.log"
    with log.open("wb") as out:
        code = subprocess.run(
            command, stdout=out, stderr=subprocess.STDOUT, timeout=900, check=False
        ).returncode
    if code != 0 or not record.is_file():
        print(f"  lockstep run failed (exit {code}):\n{log.read_text(errors='replace')[-2000:]}")
        return None
    data = np.load(record)
    return tracking_rms(data["stamp_ns"] * 1e-9, data["position"], 2.0, SECONDS - 2.0)


def offline_with_delay(period: float, delay: int) -> tuple[np.ndarray | None, float | None]:
    """case1 FPDESO tracking RMS (rad, per joint) of the offline loop on the bench plant with every command
    applied ``delay`` periods late (the applied torque fed back, as the bridge reports it).

    Returns:
        (RMS, None), or (None, t in s) when the loop diverged at t (a non-finite torque or position).
    """
    from smm_analysis.closed_loop import scenario_plant_config
    from smm_analysis.scenarios import get_scenario
    from smm_controller.chain import build_chain
    from smm_controller.td import TrackingDifferentiatorConfig
    from smm_sim.plant import SimulatedPlant

    from smm_dynamics import SMMParameters

    spec = get_scenario("case1")
    config = scenario_plant_config(spec, control_period=period)
    plant = SimulatedPlant(
        dataclasses.replace(config, encoder_counts_per_rev=COUNTS, torque_limit=(FULL_SCALE, FULL_SCALE))
    )
    h = max(period, 1e-3)
    td = TrackingDifferentiatorConfig(filter_factor=(h, h))
    chain = build_chain("fpdeso", SMMParameters(), td=td)
    steps = round(SECONDS / period)
    t = np.arange(steps + 1) * period
    reference = spec.reference().sample(t).tolist()
    queue = [(0.0, 0.0)] * delay
    position = np.empty((steps + 1, 2))
    for k in range(steps + 1):
        y0, y1, applied0, applied1 = plant.measure_floats()
        position[k] = plant.state_floats[:2]
        torque = chain.step_floats((y0, y1), (applied0, applied1), reference[k], period)
        if not (np.all(np.isfinite(position[k])) and math.isfinite(torque[0]) and math.isfinite(torque[1])):
            return None, float(t[k])
        queue.append(torque)
        plant.step(queue.pop(0), period)
    return tracking_rms(t, position, 2.0, SECONDS - 2.0), None


LOOPS: dict[str, tuple[str, dict[str, str]]] = {
    "topics": ("topics", {}),
    "direct": ("direct", {}),
    "direct-5ms": ("direct", {"loop.switch_interval": "0.005"}),
    "direct-sleep": ("direct", {"loop.spin_us": "0"}),
}
"""Loops the HIL runs: (``--loop``, the direct loop's parameters beside its defaults). ``direct-5ms`` is the
direct loop at Python's own switch interval: what the GIL costs the I/O thread; ``direct-sleep`` without
polling before the frame is due: what waking from idle costs it (docs/LAUNCH.md). Both at 1 kHz only,
the first at normal priority, the second under SCHED_FIFO."""


def realtime_hil(
    workdir: Path, period: float, host_fifo: bool = False, loop: str = "topics"
) -> dict[str, Any] | None:
    """Emulator (own clock) + the loop (:data:`LOOPS`) for ``SECONDS`` of armed output.

    Topics: hw_bridge_node + controller_node; direct: one direct_loop process. ``host_fifo``: the loop's
    processes under SCHED_FIFO too (the emulator always is, if allowed).
    """
    from smm_bringup.graph import build_graph
    from smm_bringup.graph_nodes import CONTROLLER_NODE, HW_NODE
    from smm_bringup.graph_options import GraphOptions
    from smm_bringup.realtime import (
        BOARD_PRIORITY_OFFSET,
        DEFAULT_HARDWARE_PRIORITY,
        fifo,
        fifo_allowed,
    )
    from smm_hw_bridge.run_verdict import EXIT_NOT_CONTROLLED

    tag = f"{period}_{loop}" + ("_fifo" if host_fifo else "")
    shape, loop_parameters = LOOPS[loop]

    host, board, control = free_port(), free_port(), free_port()
    record = workdir / f"hil_{tag}.npz"
    status_file = workdir / f"status_{tag}.json"
    board_seconds = SECONDS + 12.0
    period_ns = round(period * 1e9)
    processes: list[subprocess.Popen[bytes]] = []
    logs = []

    def start(name: str, argv: list[str], priority: int = 0) -> subprocess.Popen[bytes]:
        log = (workdir / f"{name}_{tag}.log").open("wb")
        logs.append(log)
        process = subprocess.Popen(
            argv,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            preexec_fn=fifo(priority).preexec() if priority and fifo_allowed(priority) else None,  # noqa: PLW1509
        )
        processes.append(process)
        return process

    board_priority = DEFAULT_HARDWARE_PRIORITY + BOARD_PRIORITY_OFFSET
    host_priority = DEFAULT_HARDWARE_PRIORITY if host_fifo else 0
    lock = []
    if period > 0.001:  # the default hydraulic lock rings too fast for a slower tick (docs/BENCH.md)
        softer = workdir / f"lock_{period}.yaml"
        softer.write_text("lock_stiffness: [150.0, 150.0]\nlock_damping: [5.0, 5.0]\n")
        lock = ["--bench-file", str(softer)]
    emulator = start("emulator", [
        sys.executable, "-m", "smm_bench_emulator.cli", "--bind", f"127.0.0.1:{board}", "--host",
        f"127.0.0.1:{host}", "--control", f"127.0.0.1:{control}", "--no-valve-lag", "--counts-per-rev",
        str(COUNTS), "--full-scale-torque", str(FULL_SCALE), "--duration", str(board_seconds), "--record",
        str(record), "--control-period", str(period), "--status-file", str(status_file), *lock,
    ], board_priority)  # fmt: skip
    bridge = {
        "autostart": "true",
        "link.bind_port": str(host),
        "link.board_port": str(board),
        "link.configure_timeout": "10.0",
        "bridge.encoder.counts_per_rev": f"[{COUNTS}, {COUNTS}]",
        "bridge.valve.gain": f"[{32767 / FULL_SCALE}, {32767 / FULL_SCALE}]",
        "bridge.valve.rate_limit": "[1.0e12, 1.0e12]",
        "bridge.valve.time_constants": "[0.0, 0.0]",  # the emulator runs without valve lag
        # the bridge's limits are 10/20/100 ticks at 1 kHz by default: the same in ticks at any period
        "bridge.admission.period_ns": str(period_ns),
        "bridge.admission.stale_ns": str(20 * period_ns),
        "bridge.host_watchdog_ns": str(10 * period_ns),
        "bridge.link_timeout_ns": str(100 * period_ns),
        # a loop the preflight finds too slow is measured all the same (its refusal is in the bridge's log)
        "preflight.force": "true",
    }
    bridge.update(loop_parameters)
    arguments = [text for name, value in bridge.items() for text in ("-p", f"{name}:={value}")]
    options = GraphOptions(
        clock_mode="realtime",
        scenario="case1",
        params_files=(str(td_yaml(workdir, period)),),
    )
    spec = next(s for s in build_graph(options) if s.name == CONTROLLER_NODE)
    controller_log, bridge_log = "controller_node", "hw_bridge_node"
    if shape == "direct":
        # one process hosting both nodes: controller_node's arguments without its __node remapping
        controller = dataclasses.replace(spec, hosts=(CONTROLLER_NODE, HW_NODE)).ros_arguments()
        controller_log = bridge_log = "direct_loop"
        direct_argv = [sys.executable, "-m", "smm_direct_loop.host", *controller, *arguments]
        start("direct_loop", direct_argv, host_priority)
    else:
        bridge_argv = [sys.executable, "-m", "smm_hw_bridge.bridge_node", "--ros-args", "-r", "__ns:=/smm"]
        start("hw_bridge_node", [*bridge_argv, *arguments], host_priority)
        start(
            "controller_node",
            [sys.executable, "-m", "smm_controller.controller_node", *spec.ros_arguments()],
            host_priority,
        )
    try:
        emulator.wait(timeout=board_seconds + 120.0)
    except subprocess.TimeoutExpired:
        print("  the emulator did not finish")
        return None
    finally:
        for process in processes[1:]:
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGINT)
        for process in processes:
            try:
                process.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
        for log in logs:
            log.close()
    if (
        emulator.returncode not in (0, EXIT_NOT_CONTROLLED)
        or not record.is_file()
        or not status_file.is_file()
    ):
        print(f"  the emulator failed (exit {emulator.returncode})")
        return None
    status: dict[str, Any] = json.loads(status_file.read_text())
    verdict = "controlled" if status["verdict"] is None else f"did not control: {status['verdict']}"
    print(f"  run: {status['figures']}; {verdict}")
    host_log = (workdir / f"{bridge_log}_{tag}.log").read_text(errors="replace")
    for line in re.findall(r"preflight: (late .*|ARMING ANYWAY.*?: this host does not hold [^:]*)", host_log):
        print(f"  preflight: {line}")
    data = np.load(record)
    ticks, q, codes = data["tick"], data["position"], data["codes"]
    live = np.flatnonzero(np.any(codes != 0, axis=1))
    if live.size == 0:
        print("  the output never went live")
        return None
    t = ticks * period
    start_t = math.ceil(t[live[0]] + 1.0)
    seconds = min(SECONDS, float(t[-1]) - start_t)
    seconds -= seconds % 2.0  # whole periods of the 2 s reference
    # The controller's time zero: the stamp of its first measurement, which it logs; the bridge stamps
    # measurements with board tick * period, so it is a time on the board's clock.
    logged = (workdir / f"{controller_log}_{tag}.log").read_text(errors="replace")
    # The last origin it logged: the preflight's rehearsal logs one before the run restarts the reference.
    origins = re.findall(r"reference t = 0 s at measurement stamp (\d+) ns", logged)
    if not origins:
        print("  the controller did not log its reference origin")
        return None
    status["origin_s"] = int(origins[-1]) * 1e-9
    status["rms"] = tracking_rms(t, q, start_t, seconds, status["origin_s"])
    status["window_s"] = seconds
    bad = np.flatnonzero(~np.all(np.isfinite(q), axis=1) | np.any(np.abs(q) > 2 * np.pi, axis=1))
    status["diverged_s"] = float(t[bad[0]]) if bad.size else None
    return status


def compare(workdir: Path, period: float) -> bool:
    """Lockstep reference and real-time HIL at ``period``, printed side by side; False if a run failed."""
    from bench_graph import timer_floor

    rate = f"{1 / period:.0f} Hz"
    start = time.monotonic()
    reference = lockstep_reference(workdir, period)
    if reference is None:
        return False
    print(
        f"{rate} lockstep simulator, case1 FPDESO, same plant: tracking RMS alpha {reference[0]:.3e}, "
        f"beta {reference[1]:.3e} rad ({time.monotonic() - start:.0f} s of wall time)"
    )
    delayed, diverged_at = offline_with_delay(period, 1)
    if delayed is None:
        print(
            f"{rate} offline loop, same plant, every command one period late: diverged at t = "
            f"{diverged_at:.3f} s (the controller has no delay margin at this rate)"
        )
    else:
        print(
            f"{rate} offline loop, same plant, every command one period late: tracking RMS alpha "
            f"{delayed[0]:.3e}, beta {delayed[1]:.3e} rad = {delayed[0] / reference[0]:.2f}x / "
            f"{delayed[1] / reference[1]:.2f}x lockstep (the controller's own delay margin)"
        )
    ok = True
    for host_fifo, loop in [(fifo, loop) for fifo in (False, True) for loop in LOOPS]:
        if loop == "direct-5ms" and (host_fifo or period != PERIODS[0]):
            continue  # the GIL's cost is measured once: 1 kHz, normal priority
        if loop == "direct-sleep" and (not host_fifo or period != PERIODS[0]):
            continue  # the wake-up's cost is measured once: 1 kHz, SCHED_FIFO (the acceptance's setting)
        floor = timer_floor(3.0)
        hil = realtime_hil(workdir, period, host_fifo, loop)
        if hil is None:
            print(f"{rate} real-time HIL, {loop} loop: the run failed (logs above)")
            ok = False
            continue
        late, enabled, applied = hil["late_commands"], hil["enabled_ticks"], hil["applied"]
        ratio = hil["rms"] / reference
        met = bool(np.all(ratio <= RMS_RATIO_TARGET))
        diverged = not np.all(np.isfinite(hil["rms"]))
        if diverged:
            at = hil["diverged_s"]
            print(f"{rate} real-time HIL, {loop} loop: the tracking diverged at t = {at:.3f} s")
        print(
            f"{rate} real-time HIL, {loop} loop, board-clocked, host at "
            f"{'SCHED_FIFO' if host_fifo else 'normal priority'}"
            f", {hil['window_s']:.0f} s armed: late commands {100 * late / max(enabled, 1):.2f} % of "
            f"enabled ticks ({late} of {enabled}: no answer to the last feedback yet), held without any new "
            f"command {100 * (enabled - applied) / max(enabled, 1):.2f} %; board overruns {hil['overruns']}; "
            f"feedback-to-command latency p50 {hil['latency_p50_us']:.0f} us, p99 "
            f"{hil['latency_p99_us']:.0f} us (kernel arrival; the emulator read them at p50 "
            f"{hil.get('read_latency_p50_us') or math.nan:.0f} us, p99 "
            f"{hil.get('read_latency_p99_us') or math.nan:.0f} us); tracking RMS alpha "
            f"{hil['rms'][0]:.3e}, beta "
            f"{hil['rms'][1]:.3e} rad = {ratio[0]:.2f}x / {ratio[1]:.2f}x lockstep "
            f"(target <= {RMS_RATIO_TARGET}x: {'met' if met else 'MISSED'}); host floor just before: "
            f"sleep-loop lateness p99 {floor['p99_us']:.0f} us, {100 * floor['late_fraction']:.2f} % late"
        )
    return ok


def main(argv: list[str]) -> int:
    if "--inner" not in argv:
        from bench_graph import reexec_in_private_netns

        return reexec_in_private_netns(argv, __file__, domain_base=170, domains=20)
    sys.path.insert(0, str(HERE))
    from bench_graph import timer_floor, udp_ping_pong

    timer = timer_floor(10.0)
    udp = udp_ping_pong(5.0)  # its echo process runs 5 s
    print(
        f"host floor, bare 1 ms sleep loop: wake-up lateness p50 {timer['p50_us']:.0f} us, p99 "
        f"{timer['p99_us']:.0f} us, late by more than a period {100 * timer['late_fraction']:.2f} %; "
        f"bare UDP ping-pong round trip p50 {udp['p50_us']:.0f} us, p99 {udp['p99_us']:.0f} us"
    )
    failed = False
    with tempfile.TemporaryDirectory(prefix="bench_hil_") as tmp:
        for period in PERIODS:
            failed |= not compare(Path(tmp), period)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
