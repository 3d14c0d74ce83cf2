"""Hours of recording: the simulated graph in lockstep, recorded with file splits, for a given wall time.

    python tools/record_hours.py --minutes 60 --out out/record_hours [--max-size BYTES] [--max-duration S]

Prints the recorder's RSS (and every node's) over time with its slope per hour, the files, the counts per file
and topic, the recorder's loss report and the stamps re-read across the splits. Exit 1 when a message was
lost, a sample is missing, the counts disagree with metadata.yaml or a traceback was logged; else 0.
Never decides on timing. Figures and how to read them: docs/SOAK.md, "Hours of recording".
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from long_runs import WARMUP_S, LaunchedGraph, check_bag, dump_json, verdict

STAMPED = ("/smm/joint_states", "/smm/torque_command", "/clock")


def build_parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=5.0, help="wall-clock minutes to record (> 0)")
    parser.add_argument(
        "--out", type=Path, default=Path("out/record_hours"), help="new folder for bag and log"
    )
    parser.add_argument("--max-size", type=int, default=256 * 2**20, help="split size (bytes, 0 = never)")
    parser.add_argument("--max-duration", type=float, default=0.0, help="split duration (s, 0 = never)")
    parser.add_argument("--sample-every", type=float, default=10.0, help="RSS sampling period (s)")
    parser.add_argument("--scenario", default="case2", help="smm-launch scenario")
    return parser


def run(arguments: argparse.Namespace) -> int:
    """Records, checks, prints; the exit code (module docstring)."""
    if arguments.minutes <= 0 or arguments.sample_every <= 0:
        print("error: --minutes and --sample-every must be > 0", file=sys.stderr)
        return 2
    out: Path = arguments.out
    if out.exists():
        print(f"error: {out} exists; choose a new folder", file=sys.stderr)
        return 2
    out.mkdir(parents=True)
    bag = out / "bag"
    launch = [
        "--plant", "sim", "--clock-mode", "lockstep", "--scenario", arguments.scenario, "--duration", "0",
        "--record", str(bag), "--record-max-size", str(arguments.max_size),
        "--record-max-duration", repr(arguments.max_duration),
    ]  # fmt: skip
    print(f"smm-launch {' '.join(launch)}", flush=True)
    graph = LaunchedGraph(launch, out / "launch.log")
    end = time.monotonic() + arguments.minutes * 60
    next_print = 0.0
    while time.monotonic() < end and graph.process.poll() is None:
        graph.sample()
        if graph.elapsed() >= next_print:
            recorder = [s for s in graph.series if s.name == "recorder_node" and s.kib]
            rss = f"{recorder[-1].kib[-1] / 1024:.1f} MiB" if recorder else "-"
            print(f"{graph.elapsed() / 60:6.1f} min: recorder RSS {rss}", flush=True)
            next_print += 300.0
        time.sleep(arguments.sample_every)
    ended_early = graph.process.poll() is not None
    code = graph.stop()
    print(f"smm-launch exit code {code}{' (ended before the time was up)' if ended_early else ''}")
    for series in graph.series:
        print(series.summary(WARMUP_S))
    result = check_bag(bag, STAMPED, 1_000_000)
    for line in result.lines():
        print(line)
    failures = []
    if result.error is not None:
        failures.append(result.error)
    if result.lost or result.missing:
        failures.append(f"{result.lost} lost, {result.missing} samples missing")
    if graph.tracebacks:
        failures.append(f"tracebacks in the log at {', '.join(graph.tracebacks)}")
    if ended_early or code not in (0, 130):
        failures.append(f"smm-launch ended with {code}")
    dump_json(
        out / "figures.json",
        {
            "minutes": arguments.minutes,
            "series": [
                {
                    "name": s.name,
                    "pid": s.pid,
                    "slope_mib_h": s.slope_mib_per_hour(WARMUP_S),
                    "kib": s.kib[-1:],
                }
                for s in graph.series
            ],
            "files": result.files,
            "topics": result.topic_counts,
            "stamps": result.stamps,
            "lost": result.lost,
            "failures": failures,
        },
    )
    return verdict(failures)


def main() -> int:
    """Console entry."""
    return run(build_parser().parse_args())


if __name__ == "__main__":
    sys.exit(main())
