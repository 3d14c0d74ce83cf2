"""Benchmark of the preflight's prediction: the rehearsed late share against the run that follows (issue 47).

Figures, not pass/fail; every process in a private network namespace (as bench_preflight.py). Makes
``--runs`` (default 5) default hardware runs (``smm-launch --plant hardware --clock-mode realtime --scenario
case1 --duration 20 --force``: ``--force`` so that each run arms and gives a pair) and prints a table: the
preflight's late share at 1 kHz, whether it would have armed without ``--force``, the run's late share (the
``run:`` line), the difference and the 1-minute load average before the run. ``--record DIR`` records each run
(the recorder's load too). Busy: ``python tools/under_load.py --busy 2 -- .venv/bin/python
bench/bench_rehearsal.py``.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
os.environ.setdefault("SMM_BENCH_PREFLIGHT_SECONDS", "20")
RUN = re.compile(r"run: .*?\(late ([0-9]+) of ([0-9]+) periods .*?\(([0-9.]+) %\)")


def load_average() -> float:
    """The 1-minute load average."""
    return float(Path("/proc/loadavg").read_text().split()[0])


def main(argv: list[str]) -> int:
    if "--inner" not in argv:
        sys.path.insert(0, str(HERE))
        from bench_graph import reexec_in_private_netns

        return reexec_in_private_netns(argv, __file__, domain_base=200, domains=10)
    parser = argparse.ArgumentParser()
    parser.add_argument("--inner", action="store_true")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--record", type=Path, default=None, help="record each run to a bag in this folder")
    parser.add_argument("--label", default="")
    parser.add_argument("--preflight", type=float, default=None, help="smm-launch --preflight S")
    options = parser.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from bench_preflight import launch

    rows: list[tuple[str, str, str, str, str, str]] = []
    if options.record is not None:
        options.record.mkdir(parents=True, exist_ok=True)
    for number in range(options.runs):
        load = load_average()
        bag = [] if options.record is None else ["--record", str(options.record / f"bag{number + 1}")]
        rehearse = [] if options.preflight is None else ["--preflight", f"{options.preflight:g}"]
        extra = ["--force", *rehearse, *bag]
        run = launch(f"run {number + 1}", 1000, extra)
        predicted = run.predicted.get(1000.0)
        found = run.first(RUN)
        held = run.first(re.compile(r"preflight: 1000 Hz holds here"))
        late = None if found is None else float(found.group(3))
        difference = "" if predicted is None or late is None else f"{late - predicted:+.2f}"
        rows.append(
            (
                "" if predicted is None else f"{predicted:.2f} %",
                "yes" if held else "no",
                "" if late is None else f"{late:.2f} %",
                difference,
                f"{load:.1f}",
                str(run.code),
            )
        )
    print("\n| run | prediction (1 kHz) | would arm | run late | run - prediction (points) | load | exit |")
    print("|---|---|---|---|---|---|---|")
    for number, row in enumerate(rows, 1):
        print(f"| {options.label} {number} | " + " | ".join(row) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
