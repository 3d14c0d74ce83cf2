"""``smm_bench_emulator --link canopen``: the emulated CANopen bench as a process, its end-of-run status."""

from __future__ import annotations

import json
import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import Any

from smm_hw_bridge.can_multicast import MulticastRouteError, loopback_multicast_bus

from smm_bench_emulator.board import BoardConfig
from smm_bench_emulator.canopen_bench import CanBench, CanBenchConfig

__all__ = ["run_canopen", "status"]


def status(bench: CanBench, never_started: bool) -> dict[str, Any]:
    """The end-of-run status, with the frame emulator's keys smm-launch reads (lockstep: none late)."""
    verdict = "the controller never armed the valves (no SYNC with both ACTIVE)" if never_started else None
    states = [state.name for state in bench.valve_states()]
    return {
        "link": "canopen",
        "syncs": bench.syncs,
        "live_ticks": bench.live_syncs,
        "enabled_ticks": bench.active_syncs,
        "late_commands": 0,
        "latency_p50_us": None,
        "latency_p99_us": None,
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
    duration_s: float,
    start_timeout_s: float,
    status_file: str,
) -> int:
    """Runs the bench on the loopback multicast group until SIGTERM or ``duration_s`` live; the exit code."""
    try:
        bus = loopback_multicast_bus(group, port)
        config = CanBenchConfig(
            board=board, wait_active=lockstep, duration_syncs=round(duration_s * 1e9 / board.period_ns)
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
        if start_timeout_s > 0 and not bench.done.wait(start_timeout_s) and bench.active_syncs == 0:
            never_started = True
        else:
            bench.done.wait()
    finally:
        bench.close()
    summary = json.dumps(status(bench, never_started and not stop.is_set()))
    if status_file:
        Path(status_file).write_text(summary)
    print(summary, flush=True)
    return 3 if never_started and not stop.is_set() else 0
