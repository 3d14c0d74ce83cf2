"""Benchmark of the preflight: does the default hardware run hold its rate, or refuse with the rate it holds?

Figures, not pass/fail (``make bench``); every process in a private network namespace (as bench_hil.py).
The acceptance of issue 32, three ``smm-launch --plant hardware --clock-mode realtime --scenario case1`` runs:

1. The default run (the direct loop, 1000 Hz control): it holds its rate within the late limit (exit 0), or
   refuses at preflight (exit 4) with its figures and the fastest candidate rate it holds.
2. The run at that rate (``--control-rate``): it holds it.
3. The next faster candidate rate with ``--force``: it exceeds the limit (exit 3).

Each run prints the preflight's prediction for its rate beside the board's late share of the run (the
emulator's ``board:`` line); then ``SMM_BENCH_PREFLIGHT_COMPARE`` (default 3) runs of the default with
``--force`` compare the prediction with the real run's figures. Beside load:
``python tools/under_load.py --busy 2 -- .venv/bin/python bench/bench_preflight.py``.
``SMM_BENCH_PREFLIGHT_SECONDS`` (default 15): armed seconds per run; ``SMM_BENCH_PREFLIGHT_REPEAT`` (default
1): how many times the three runs are made.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
SECONDS = float(os.environ.get("SMM_BENCH_PREFLIGHT_SECONDS", "15"))
REPEAT = int(os.environ.get("SMM_BENCH_PREFLIGHT_REPEAT", "1"))
COMPARE = int(os.environ.get("SMM_BENCH_PREFLIGHT_COMPARE", "3"))
RATES_HZ = (1000, 500, 250, 200, 100)
"""The candidate control rates, fastest first (a 1 kHz board)."""
EXIT_NAMES = {0: "controlled", 3: "did not control", 4: "refused at preflight"}

PREDICTED = re.compile(r"preflight: late ([0-9.]+) % of control periods .*predicted: (.*)$")
PREDICTED_RATE = re.compile(r"([0-9.]+) % at ([0-9.]+) Hz")
LATENCY = re.compile(r"preflight: feedback->command .*?: p50 ([0-9]+) us, p99 ([0-9]+) us")
WAKEUP = re.compile(r"preflight: wake-up .*?: p50 ([0-9]+) us, p99 ([0-9]+) us")
HOLDS = re.compile(r"fastest candidate rate it holds is ([0-9.]+) Hz")
BOARD = re.compile(r"board: late ([0-9]+) of ([0-9]+) enabled ticks \(([0-9.]+) %\), feedback->command (.*)$")


@dataclass
class Run:
    """One ``smm-launch`` run and what its output says."""

    label: str
    rate_hz: int
    code: int
    lines: list[str]

    def first(self, pattern: re.Pattern[str]) -> re.Match[str] | None:
        for line in self.lines:
            found = pattern.search(line)
            if found:
                return found
        return None

    @property
    def predicted(self) -> dict[float, float]:
        """Rate (Hz) -> the preflight's predicted late share (%)."""
        found = self.first(PREDICTED)
        if found is None:
            return {}
        return {float(rate): float(share) for share, rate in PREDICTED_RATE.findall(found.group(2))}

    @property
    def fastest_held(self) -> int | None:
        found = self.first(HOLDS)
        return None if found is None else round(float(found.group(1)))

    def summary(self) -> str:
        outcome = EXIT_NAMES.get(self.code, "failed")
        parts = [f"{self.label}: exit {self.code} ({outcome})"]
        predicted = self.predicted
        if predicted:
            share = predicted.get(float(self.rate_hz))
            parts.append(
                f"preflight predicted {share:.2f} % late at {self.rate_hz} Hz"
                if share is not None
                else "preflight ran"
            )
            latency, wakeup = self.first(LATENCY), self.first(WAKEUP)
            if latency:
                parts.append(f"rehearsal feedback->command p50 {latency[1]} / p99 {latency[2]} us")
            if wakeup:
                parts.append(f"wake-up p50 {wakeup.group(1)} / p99 {wakeup.group(2)} us")
        board = self.first(BOARD)
        if board:
            parts.append(f"run: late {board[3]} % ({board[1]} of {board[2]}), {board[4]}")
        if self.fastest_held is not None:
            parts.append(f"refusal names {self.fastest_held} Hz")
        return "; ".join(parts)


def launch(label: str, rate_hz: int, extra: list[str]) -> Run:
    """One hardware run of ``SECONDS`` armed seconds; its output is kept and the preflight lines shown."""
    command = [
        sys.executable,
        "-m",
        "smm_bringup.launcher",
        "--plant",
        "hardware",
        "--clock-mode",
        "realtime",
        "--scenario",
        "case1",
        "--duration",
        str(SECONDS),
        *extra,
    ]
    print(f"$ smm-launch {' '.join(command[3:])}", flush=True)
    started = time.monotonic()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    lines = (done.stdout + done.stderr).splitlines()
    for line in lines:
        if "preflight:" in line or line.startswith("[smm-launch] board:") or "run:" in line:
            print(f"    {line[line.find('preflight:') if 'preflight:' in line else 0 :]}", flush=True)
    print(f"    ({time.monotonic() - started:.0f} s)", flush=True)
    return Run(label, rate_hz, done.returncode, lines)


def faster(rate_hz: int) -> int | None:
    """The next faster candidate rate, None for the fastest."""
    index = RATES_HZ.index(rate_hz)
    return RATES_HZ[index - 1] if index > 0 else None


def has_control_rate() -> bool:
    """True when this build's smm-launch takes ``--control-rate``."""
    command = [sys.executable, "-m", "smm_bringup.launcher", "--help"]
    return "--control-rate" in subprocess.run(command, capture_output=True, text=True, check=False).stdout


def acceptance() -> list[Run]:
    """The three runs of the module docstring (fewer when the default run holds at the fastest rate)."""
    default = launch("1. default run (direct loop, 1000 Hz)", RATES_HZ[0], [])
    runs = [default]
    if not has_control_rate():
        print("    (this build's smm-launch has no --control-rate: runs 2 and 3 need it)", flush=True)
        return runs
    if default.code == 0:
        held = RATES_HZ[0]
    elif default.code == 4 and default.fastest_held is not None:
        held = default.fastest_held
        runs.append(launch(f"2. at the rate it holds ({held} Hz)", held, ["--control-rate", str(held)]))
    else:
        return runs
    quicker = faster(held)
    if quicker is not None:
        runs.append(
            launch(
                f"3. the next faster rate ({quicker} Hz) with --force",
                quicker,
                ["--control-rate", str(quicker), "--force"],
            )
        )
    return runs


def main(argv: list[str]) -> int:
    if "--inner" not in argv:
        sys.path.insert(0, str(HERE))
        from bench_graph import reexec_in_private_netns

        return reexec_in_private_netns(argv, __file__, domain_base=190, domains=10)
    uptime = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    print(f"uptime before: {uptime} (a shared machine: other sessions' load counts)", flush=True)
    every: list[Run] = []
    for repeat in range(REPEAT):
        print(f"\n--- round {repeat + 1} of {REPEAT}, {SECONDS:g} s armed per run ---", flush=True)
        every += acceptance()
    for compare in range(COMPARE):
        label = f"prediction vs run {compare + 1}: the default with --force"
        every.append(launch(label, RATES_HZ[0], ["--force"]))
    print("\nsummary (preflight's prediction against the run's own late share, board clock):")
    for run in every:
        print(f"  {run.summary()}")
    uptime = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    print(f"uptime after: {uptime}")
    return 0 if all(run.code in EXIT_NAMES for run in every) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
