"""Long bags: time and peak RSS of ``smm-bag analyze``, ``rerun`` and ``identify`` on 1 kHz bags.

Run by ``make bench``. For each length in ``--minutes`` (default 1 and 60) a case-2 FPDESO run of the
offline loop (one minute, repeated back to back for longer bags) is written as a bag into a temporary
directory (its own process, not measured), and for ``identify`` an ``excite`` run (its 11 s repeated to the
length); then ``smm-bag analyze``, ``rerun`` (``rerun.csv`` written) and ``identify``, each ``BAG --out
DIR`` and as its own process, and their wall time, CPU time and peak RSS (``ru_maxrss`` of that process
alone, from ``os.wait4``) are printed, with the ratios of issue 33's acceptance: the longest run's peak RSS
against the shortest's (target <= 1.2x) and its time against the shortest's (target <= the length ratio).
``--against-memory``: also the indices of the longest case-2 bag computed in memory (``load_run`` and
``evaluate``, as ``analyze`` did before it streamed; about 2.8 MiB of memory per MiB of bag) against the
streamed ones, with the largest relative difference and the stated tolerance. Figures only; nothing asserts.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_GENERATE = """
import sys
from pathlib import Path
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_analysis.scenarios import get_scenario
minutes, block, path, scenario = float(sys.argv[1]), float(sys.argv[2]), Path(sys.argv[3]), sys.argv[4]
if scenario == "excite":  # the excitation's own length, repeated
    trajectory = run_closed_loop(get_scenario("excite"), "fpdeso", seed=0)
    repeat = max(1, round(60.0 * minutes / (trajectory.t_ns.size * trajectory.control_period)))
else:
    piece = min(minutes, block)
    repeat = max(1, round(minutes / piece))
    trajectory = run_closed_loop(get_scenario(scenario).with_duration(60.0 * piece), "fpdeso", seed=0)
metadata = write_trajectory_bag(trajectory, path, repeat=repeat)
print(metadata.message_count)
"""
_AGAINST_MEMORY = """
import sys
from smm_analysis.runs.accumulate import SUM_RELATIVE_TOLERANCE
from smm_analysis.runs.indices import evaluate, evaluate_stream
from smm_analysis.runs.recorded import load_run
from smm_analysis.runs.stream import StepStream
streamed = evaluate_stream(StepStream(sys.argv[1]))
in_memory = evaluate(load_run(sys.argv[1]))
worst, exact = 0.0, True
for joint, indices in in_memory.joints.items():
    exact &= streamed.joints[joint].Ma == indices.Ma
    for name in ("Ave", "RMS", "eps_u", "du_rms"):
        a, b = getattr(streamed.joints[joint], name), getattr(indices, name)
        worst = max(worst, abs(a - b) / abs(b) if b else abs(a))
for axis, error in in_memory.end_effector.items():
    exact &= streamed.end_effector[axis].max_mm == error.max_mm
    a, b = streamed.end_effector[axis].rms_mm, error.rms_mm
    worst = max(worst, abs(a - b) / abs(b) if b else abs(a))
exact &= streamed.run.steps == in_memory.run.steps
print(f"steps {streamed.run.steps:,} both; maxima and counts {'equal' if exact else 'DIFFER'}; "
      f"largest relative difference of the sums {worst:.1e} (tolerance {SUM_RELATIVE_TOLERANCE:g}): "
      f"{'within' if exact and worst <= SUM_RELATIVE_TOLERANCE else 'OUTSIDE'}")
"""
_BLOCK_MINUTES = 1.0
"""Longer bags repeat a run of this many minutes back to back (the offline loop holds its whole run, about
2 GiB per 10 minutes with every internal): every length holds the same signals, so the figures compare."""


def measured(command: list[str]) -> tuple[int, float, float, float]:
    """Runs ``command``; returns its exit code, wall time (s), CPU time (s) and peak RSS (MiB) of it alone."""
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    start = time.perf_counter()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert process.stderr is not None
    errors = process.stderr.read()
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - start
    process.returncode = os.waitstatus_to_exitcode(status)
    if process.returncode != 0:
        print(f"  {' '.join(command[:3])} exited {process.returncode}: {errors.decode()[-500:]}")
    return process.returncode, wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


SCENARIO_OF = {"analyze": "case2", "rerun": "case2", "identify": "excite"}
"""The run each command is measured on."""


def generate(minutes: float, bag: Path, scenario: str) -> int:
    """Writes a ``minutes``-long bag of ``scenario`` (offline loop); returns its message count."""
    result = subprocess.run(
        [sys.executable, "-c", _GENERATE, str(minutes), str(_BLOCK_MINUTES), str(bag), scenario],
        check=True,
        capture_output=True,
        text=True,
    )
    return int(result.stdout.split()[-1])


def against_memory(bag: Path) -> None:
    """Prints the streamed indices of ``bag`` against the in-memory computation (one process, both)."""
    start = time.perf_counter()
    process = subprocess.Popen(
        [sys.executable, "-c", _AGAINST_MEMORY, str(bag)], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    output, errors = process.communicate()
    wall = time.perf_counter() - start
    if process.returncode != 0:
        print(f"  in memory: exited {process.returncode}: {errors.decode()[-500:]}")
        return
    print(f"  in memory vs streamed ({wall:.0f} s, both in one process): {output.decode().strip()}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", default="1,60", help="comma-separated bag lengths (min), default 1,60")
    parser.add_argument(
        "--commands", default="analyze,rerun,identify", help="which of analyze,rerun,identify to measure"
    )
    parser.add_argument(
        "--against-memory",
        action="store_true",
        help="also compare the longest case-2 bag's streamed indices with the in-memory computation",
    )
    arguments = parser.parse_args(sys.argv[1:] if argv is None else argv)
    lengths = [float(value) for value in arguments.minutes.split(",")]
    commands = [name.strip() for name in arguments.commands.split(",") if name.strip()]
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores (shared machine: times vary)")
    results: dict[tuple[str, float], tuple[float, float, float]] = {}
    failed = False
    with tempfile.TemporaryDirectory(prefix="bench_long_bag_") as directory:
        workdir = Path(directory)
        for minutes in lengths:
            for scenario in dict.fromkeys(SCENARIO_OF[name] for name in commands):
                bag = workdir / f"{scenario}_{minutes:g}min"
                start = time.perf_counter()
                count = generate(minutes, bag, scenario)
                size = sum(p.stat().st_size for p in bag.iterdir()) / 2**20
                print(
                    f"{minutes:g} min {scenario} bag: {count:,} messages, {size:,.0f} MiB "
                    f"(generated in {time.perf_counter() - start:.0f} s)"
                )
                for name in (name for name in commands if SCENARIO_OF[name] == scenario):
                    out = workdir / f"out_{name}_{minutes:g}"
                    command = [sys.executable, "-m", "smm_bag.cli", name, str(bag), "--quiet"]
                    command += ["--out", str(out)]
                    code, wall, cpu, rss = measured(command)
                    shutil.rmtree(out, ignore_errors=True)
                    failed |= code != 0
                    results[(name, minutes)] = (wall, cpu, rss)
                    print(f"  smm-bag {name}: wall {wall:7.1f} s, CPU {cpu:7.1f} s, peak RSS {rss:6.0f} MiB")
                if arguments.against_memory and scenario == "case2" and minutes == max(lengths):
                    against_memory(bag)
                for path in bag.iterdir():
                    path.unlink()
                bag.rmdir()
    shortest, longest = min(lengths), max(lengths)
    if longest > shortest:
        for name in commands:
            (short_wall, short_cpu, short_rss) = results[(name, shortest)]
            (long_wall, long_cpu, long_rss) = results[(name, longest)]
            print(
                f"{name}: {longest:g} min vs {shortest:g} min: peak RSS x{long_rss / short_rss:.2f} "
                f"(target <= 1.2), wall x{long_wall / short_wall:.1f}, CPU x{long_cpu / short_cpu:.1f} "
                f"(target <= {longest / shortest:g})"
            )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
