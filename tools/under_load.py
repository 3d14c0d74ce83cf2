"""Run a command beside busy processes, optionally all pinned to some CPUs (docs/TESTING.md, "Under load").

    python tools/under_load.py --busy 2 -- env CI=true bash .ci/run
    python tools/under_load.py --busy 1 --cpus 0 -- env CI=true bash .ci/run     # as taskset -c 0
    python tools/under_load.py --busy 2 --repeat 3 -- env CI=true bash .ci/run

Each busy process spins in pure Python at normal priority. While the command runs, a thread measures the host
floor (how late a 1 ms sleep wakes up, p50/p99) so that real-time figures printed by the command can be judged
against it. Exits with the command's first non-zero exit code, else 0. Ends only the processes it started.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence

BUSY_LOOP = "while True: pass"


def parse_cpus(text: str) -> set[int]:
    """``"0"``, ``"0,1"`` or ``"0-3"`` -> the CPU numbers (as taskset -c takes them)."""
    cpus: set[int] = set()
    for part in text.split(","):
        low, _, high = part.partition("-")
        if not low.strip().isdigit() or (high and not high.strip().isdigit()):
            raise argparse.ArgumentTypeError(f"expected CPUs like 0 or 0,1 or 0-3, got {text!r}")
        cpus.update(range(int(low), int(high or low) + 1))
    return cpus


def build_parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(prog="under_load.py", description=__doc__.splitlines()[0])
    parser.add_argument("--busy", type=int, default=2, help="busy processes beside the command (default 2)")
    parser.add_argument(
        "--cpus", type=parse_cpus, default=None, help="pin the command and the busy ones here"
    )
    parser.add_argument("--repeat", type=int, default=1, help="run the command this many times (default 1)")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND [ARGS...]")
    return parser


class FloorProbe(threading.Thread):
    """Measures how late ``time.sleep(0.001)`` returns, in microseconds, until stopped."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.late_us: list[float] = []
        self.stop = threading.Event()

    def run(self) -> None:
        """Sleeps 1 ms at a time, keeping each overshoot."""
        while not self.stop.is_set():
            start = time.monotonic_ns()
            time.sleep(0.001)
            self.late_us.append((time.monotonic_ns() - start) / 1e3 - 1000.0)

    def summary(self) -> str:
        """``p50 A us, p99 B us, max C us over N sleeps``."""
        if not self.late_us:
            return "no sample"
        ordered = sorted(self.late_us)
        p50, p99 = (ordered[min(len(ordered) - 1, int(q * len(ordered)))] for q in (0.5, 0.99))
        return f"p50 {p50:.0f} us, p99 {p99:.0f} us, max {ordered[-1]:.0f} us over {len(ordered)} sleeps"


def run(argv: Sequence[str]) -> int:
    """Parse ``argv``, run the command ``--repeat`` times beside the busy processes; the exit code."""
    arguments = build_parser().parse_args(list(argv))
    command = arguments.command[1:] if arguments.command[:1] == ["--"] else arguments.command
    if not command:
        build_parser().error("no command given (put it after --)")
    if arguments.busy < 0 or arguments.repeat < 1:
        build_parser().error("--busy must be >= 0 and --repeat >= 1")
    if arguments.cpus is not None:
        os.sched_setaffinity(0, arguments.cpus)  # this process, its probe thread and every child
    busy = [
        subprocess.Popen([sys.executable, "-c", BUSY_LOOP], stdin=subprocess.DEVNULL)
        for _ in range(arguments.busy)
    ]
    where = "any CPU" if arguments.cpus is None else f"CPUs {sorted(arguments.cpus)}"
    print(f"[under_load] {len(busy)} busy processes (pids {[p.pid for p in busy]}) on {where}", flush=True)
    first_failure = 0
    try:
        for attempt in range(1, arguments.repeat + 1):
            probe = FloorProbe()
            probe.start()
            started = time.monotonic()
            code = subprocess.call(command)
            probe.stop.set()
            probe.join()
            elapsed = time.monotonic() - started
            print(
                f"[under_load] run {attempt}/{arguments.repeat}: exit {code} after {elapsed:.0f} s; "
                f"host floor (1 ms sleep overshoot) {probe.summary()}",
                flush=True,
            )
            if code and not first_failure:
                first_failure = code
    finally:
        for process in busy:
            process.send_signal(signal.SIGTERM)
        for process in busy:
            process.wait()
    return first_failure


if __name__ == "__main__":
    sys.exit(run(sys.argv[1:]))
