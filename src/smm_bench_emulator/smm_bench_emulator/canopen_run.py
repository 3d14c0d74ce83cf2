"""``smm_bench_emulator --link canopen``: the emulated CANopen bench as a process, its end-of-run status."""

from __future__ import annotations

import json
import signal
import sys
import threading
import time
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
from smm_hw_bridge.can_multicast import MulticastRouteError, loopback_multicast_bus

from smm_bench_emulator.board import BoardConfig
from smm_bench_emulator.canopen_bench import CanBench, CanBenchConfig

__all__ = ["run_canopen", "status"]

_WATCH_S = 0.002
"""Real time: how often the valves' receive deadline is checked on the wall clock (s)."""


def status(bench: CanBench, never_started: bool) -> dict[str, Any]:
    """The end-of-run status, with the frame emulator's keys smm-launch reads.

    Per SYNC: late = both valves ACTIVE and one had no new setpoint since the last SYNC (held); latency =
    the later valve's setpoint after the SYNC before it (the board's feedback -> command).
    """
    verdict = "the controller never armed the valves (no SYNC with both ACTIVE)" if never_started else None
    states = [state.name for state in bench.valve_states()]
    answers = np.asarray(bench.answer_us)
    p50, p99, worst = [None] * 3 if not answers.size else np.percentile(answers, (50, 99, 100)).tolist()
    return {
        "link": "canopen",
        "syncs": bench.syncs,
        "live_ticks": bench.live_syncs,
        "enabled_ticks": bench.active_syncs,
        "late_commands": bench.held_syncs,
        "latency_p50_us": p50,
        "latency_p99_us": p99,
        "latency_max_us": worst,
        "skipped_periods": bench.skipped_periods,
        "read_latency_p50_us": None,
        "read_latency_p99_us": None,
        "valve_states": states,
        "figures": f"{bench.syncs} SYNCs, {bench.active_syncs} with both valves ACTIVE, valves now {states}",
        "verdict": verdict,
    }


def run_canopen(
    board: BoardConfig,
    group: str,
    port: int,
    *,
    lockstep: bool,
    divider: int,
    duration_s: float,
    start_timeout_s: float,
    status_file: str,
) -> int:
    """Runs the bench on the loopback multicast group until SIGTERM or ``duration_s`` live; the exit code.

    ``divider``: board ticks per SYNC (the master's 0x1006). Live counts from both valves first ACTIVE; in
    real time the valves' receive deadline is watched on the wall clock too (no SYNC needed).
    """
    try:
        bus = loopback_multicast_bus(group, port)
        config = CanBenchConfig(
            board=board,
            wait_active=True,
            duration_syncs=round(duration_s * 1e9 / (board.period_ns * divider)),
        )
    except (MulticastRouteError, ValueError, OSError) as error:
        print(f"smm_bench_emulator: {error}", file=sys.stderr)
        return 2
    bench = CanBench(config, bus)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()
        bench.done.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    print(
        f"smm_bench_emulator: CANopen bench on {group}:{port}, valves {config.valve_node_ids}, "
        f"encoders {config.encoder_node_ids}, {'lockstep' if lockstep else 'realtime'}",
        flush=True,
    )
    never_started = False
    try:
        started = time.monotonic()
        while not bench.done.wait(1.0 if lockstep else _WATCH_S):
            if not lockstep:
                bench.watch(time.monotonic_ns())
            if 0 < start_timeout_s < time.monotonic() - started and bench.active_syncs == 0:
                never_started = True
                break
    finally:
        bench.close()
    summary = json.dumps(status(bench, never_started and not stop.is_set()))
    if status_file:
        Path(status_file).write_text(summary)
    print(summary, flush=True)
    return 3 if never_started and not stop.is_set() else 0
