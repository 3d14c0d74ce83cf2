"""The soak of the bench path: the hardware graph in real time on the emulator, recorded, under faults.

    python tools/soak.py --minutes 10 --out out/soak          (make soak SOAK_MINUTES=10)

``smm-launch --plant hardware --clock-mode realtime --loop direct --record ... --respawn`` runs for the given
wall time while the faults repeat in a cycle, each followed by a settling time: a 100 ms link blackout, a
garbage burst, a gain change, an e-stop and re-arm, a board restart, the gain back, the controlling process
killed with SIGKILL (respawned by smm-launch). Prints a per-fault table, RSS growth per hour of every process,
the longest gaps of the loop, the bag's counts and losses, tracebacks; exits 1 when a criterion failed.
Criteria and figures: docs/SOAK.md.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import soak_faults as faults
from long_runs import WARMUP_S, LaunchedGraph, check_bag, dump_json, verdict
from smm_bag.cdr import stamp_of
from smm_bag.reader import BagReader
from smm_hw_bridge.preflight import EXIT_PREFLIGHT_REFUSED

STAMPED = ("/smm/joint_states",)
JOINT_STATES = "/smm/joint_states"
PERIOD_NS = 1_000_000
WINDOW_MARGIN_S = 1.0
"""Loop gaps are measured outside each fault's window widened by this much on both sides (s)."""


def build_parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="wall-clock minutes of the soak (> 0)")
    parser.add_argument("--out", type=Path, default=Path("out/soak"), help="new folder: bag, log, figures")
    parser.add_argument(
        "--settle", type=float, default=20.0, help="seconds of undisturbed running after each fault"
    )
    parser.add_argument("--sample-every", type=float, default=10.0, help="RSS sampling period (s)")
    parser.add_argument("--max-size", type=int, default=256 * 2**20, help="bag split size (bytes)")
    parser.add_argument(
        "--launch-arg", action="append", default=[], metavar="ARG",
        help="extra smm-launch argument (repeatable), e.g. --launch-arg=--control-rate --launch-arg=500",
    )  # fmt: skip
    return parser


def uptime() -> str:
    """The ``uptime`` line (load averages)."""
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    except OSError:
        return Path("/proc/loadavg").read_text().strip()


def loop_gaps(bag: Path, windows: list[tuple[float, float]]) -> dict[str, float]:
    """Longest joint_states arrival gap and board-tick step (ms) outside the fault ``windows`` (epoch s)."""
    spans = [(int((a - WINDOW_MARGIN_S) * 1e9), int((b + WINDOW_MARGIN_S) * 1e9)) for a, b in windows]
    arrival = step = 0
    last_time = last_stamp = None
    with BagReader(bag) as reader:
        type_name = reader.topics.get(JOINT_STATES, "sensor_msgs/msg/JointState")
        for _, log_time, data in reader.raw_messages([JOINT_STATES]):
            stamp = stamp_of(type_name, data)
            inside = any(a <= log_time <= b for a, b in spans)
            if not inside and last_time is not None:
                arrival = max(arrival, log_time - last_time)
                if stamp is not None and last_stamp is not None:
                    step = max(step, stamp - last_stamp)
            last_time, last_stamp = log_time, stamp
    return {"joint_states_arrival_ms": arrival / 1e6, "board_tick_step_ms": step / 1e6}


def run(arguments: argparse.Namespace) -> int:
    """The soak; its exit code (module docstring)."""
    if arguments.minutes <= 0 or arguments.settle < 0:
        print("error: --minutes must be > 0 and --settle >= 0", file=sys.stderr)
        return 2
    out: Path = arguments.out
    if out.exists():
        print(f"error: {out} exists; choose a new folder", file=sys.stderr)
        return 2
    out.mkdir(parents=True)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(60 + os.getpid() % 40))
    load_start = uptime()
    print(f"start: {load_start}", flush=True)
    launch = [
        "--plant", "hardware", "--clock-mode", "realtime", "--loop", "direct", "--scenario", "case2",
        "--record", str(out / "bag"), "--record-max-size", str(arguments.max_size),
        "--respawn", "--respawn-delay", "1", "--respawn-limit", "1000", *arguments.launch_arg,
    ]  # fmt: skip
    print(f"smm-launch {' '.join(launch)}", flush=True)
    graph = LaunchedGraph(launch, out / "launch.log")
    board = faults.Board()
    operator = faults.Operator()
    results: list[faults.FaultResult] = []
    end = time.monotonic() + arguments.minutes * 60
    last_sample = 0.0

    def sample() -> None:
        nonlocal last_sample
        if time.monotonic() - last_sample >= arguments.sample_every:
            graph.sample()
            last_sample = time.monotonic()

    def settle(seconds: float) -> None:
        until = time.monotonic() + seconds
        while time.monotonic() < until and graph.process.poll() is None:
            sample()
            time.sleep(min(1.0, max(0.0, until - time.monotonic())))

    def controller_pid() -> int | None:
        return graph.pids.get("direct_loop")

    try:
        first = faults.wait_tracking(board, 120.0)
        print(
            f"armed and tracking {graph.elapsed():.1f} s after the start"
            if first is not None
            else "never armed"
        )
        if first is None:
            results.append(faults.FaultResult("start", time.time(), False, detail="never armed within 120 s"))
        now: Callable[[], float] = time.time
        cycle: list[Callable[[int], faults.FaultResult]] = [
            lambda _: faults.blackout(board, operator, now),
            lambda n: faults.garbage(board, operator, now, n),
            lambda n: faults.gains(board, operator, now, n),
            lambda _: faults.estop(board, operator, now),
            lambda _: faults.board_restart(board, operator, now),
            lambda n: faults.gains(board, operator, now, n),
            lambda _: kill(),
        ]

        def kill() -> faults.FaultResult:
            before = controller_pid()
            return faults.kill_controller(
                board, operator, now, before, lambda: controller_pid() not in (None, before)
            )

        index = 0
        while first is not None and time.monotonic() + 15.0 < end and graph.process.poll() is None:
            if not board.live():  # control lost since the last fault settled: a failure of its own
                lost = faults.FaultResult("lost between faults", time.time(), False)
                faults.recover(board, lost, operator.reactivate)
                lost.detail = f"not live before the next fault; {lost.operator or 'recovered by itself'}"
                lost.ended_s = time.time()
                results.append(lost)
                print(f"{graph.elapsed() / 60:6.1f} min  {lost.name:<20} FAIL {lost.detail}", flush=True)
            result = cycle[index % len(cycle)](index // len(cycle) + index)
            results.append(result)
            mark = "ok" if result.ok else "FAIL"
            print(f"{graph.elapsed() / 60:6.1f} min  {result.name:<20} {mark:4} {result.detail}", flush=True)
            index += 1
            settle(min(arguments.settle, max(0.0, end - time.monotonic())))
        settle(max(0.0, end - time.monotonic()))
    finally:
        operator.close()
        final_status = board.status() or {}
        board.close()
        ended_min = graph.elapsed() / 60 if graph.process.poll() is not None else None
        code = graph.stop()
    load_end = uptime()
    return report(
        arguments=arguments, out=out, graph=graph, results=results, code=code,
        final_status=final_status, load_start=load_start, load_end=load_end, ended_min=ended_min,
    )  # fmt: skip


def report(
    *,
    arguments: argparse.Namespace,
    out: Path,
    graph: LaunchedGraph,
    results: list,  # type: ignore[type-arg]
    code: int,
    final_status: dict,  # type: ignore[type-arg]
    load_start: str,
    load_end: str,
    ended_min: float | None = None,
) -> int:
    """Prints the tables; the exit code. ``ended_min``: when smm-launch ended by itself (min), else None."""
    failures: list[str] = []
    print(f"\nsmm-launch exit code {code}")
    if ended_min is not None:
        refused = code == EXIT_PREFLIGHT_REFUSED
        why = " (a respawn refused to arm at preflight: final, not respawned)" if refused else ""
        failures.append(f"smm-launch ended by itself after {ended_min:.1f} min with code {code}{why}")
        print(failures[-1])
    print(f"load at start: {load_start}\nload at end:   {load_end}")
    header = ("fault", "count", "failed", "null ticks max", "recovery s max", "median")
    print("\n{:<20} {:>5} {:>6} {:>15} {:>15} {:>7}".format(*header))
    for name in dict.fromkeys(result.name for result in results):
        mine = [result for result in results if result.name == name]
        nulls = [r.null_ticks for r in mine if r.null_ticks is not None]
        recoveries = sorted(r.recovery_s for r in mine if r.recovery_s is not None)
        failed = sum(not r.ok for r in mine)
        worst = f"{recoveries[-1]:.2f}" if recoveries else "-"
        median = f"{recoveries[len(recoveries) // 2]:.2f}" if recoveries else "-"
        null = max(nulls) if nulls else "-"
        print(f"{name:<20} {len(mine):>5} {failed:>6} {null:>15} {worst:>15} {median:>7}")
        if failed:
            failures.append(f"{name} failed {failed} of {len(mine)}")
    for result in results:
        if not result.ok:
            at = result.started_s - results[0].started_s
            print(f"  FAILED {result.name} at {at:.0f} s: {result.detail} {result.operator}")
    print()
    for series in graph.series:
        print(series.summary(WARMUP_S))
    bag = out / "bag"
    check = check_bag(bag, STAMPED, PERIOD_NS)
    for line in check.lines():
        print(line)
    if check.error is not None:
        failures.append(check.error)
    elif check.lost:
        failures.append(f"the recorder lost {check.lost} messages")
    gaps: dict[str, float] = {}
    if check.error is None:
        gaps = loop_gaps(bag, [(r.started_s, r.ended_s or r.started_s) for r in results])
        print(
            f"loop outside fault windows (+-{WINDOW_MARGIN_S:g} s): longest joint_states arrival gap at the "
            f"recorder {gaps['joint_states_arrival_ms']:.1f} ms, "
            f"longest board-tick step {gaps['board_tick_step_ms']:.0f} ms"
        )
    print(
        f"board (emulator) at the end: {final_status.get('ticks')} ticks, "
        f"{final_status.get('overruns')} overruns, "
        f"late {final_status.get('late_commands')} of {final_status.get('enabled_ticks')} enabled ticks"
    )
    if graph.tracebacks:
        failures.append(f"tracebacks in the log at {', '.join(graph.tracebacks)}")
    print(f"tracebacks: {len(graph.tracebacks)}")
    dump_json(
        out / "figures.json",
        {
            "minutes": arguments.minutes,
            "load_start": load_start,
            "load_end": load_end,
            "faults": [vars(result) for result in results],
            "series": [
                {
                    "name": s.name,
                    "pid": s.pid,
                    "minutes": (s.times_s[-1] - s.times_s[0]) / 60 if s.times_s else 0,
                    "first_mib": s.kib[0] / 1024 if s.kib else None,
                    "last_mib": s.kib[-1] / 1024 if s.kib else None,
                    "slope_mib_h": s.slope_mib_per_hour(WARMUP_S),
                }
                for s in graph.series
            ],
            "bag_files": check.files,
            "stamps": check.stamps,
            "lost": check.lost,
            "gaps": gaps,
            "board": final_status,
            "failures": failures,
        },
    )
    return verdict(failures)


def main() -> int:
    """Console entry."""
    return run(build_parser().parse_args())


if __name__ == "__main__":
    sys.exit(main())
