"""The CANopen benchmarks' runs: one ``smm-launch --plant hardware --link canopen`` run, what its closing
lines say (the bridge's ``host:`` line, the emulator's status, the preflight's verdict), a bag's tracking RMS.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
LAUNCH = (sys.executable, "-m", "smm_bringup.launcher", "--plant", "hardware", "--link", "canopen")
UNDER_LOAD = (sys.executable, str(REPO / "tools" / "under_load.py"))
HOST = re.compile(
    r"host: late (\d+) of (\d+) periods of ([0-9.]+) ms .*?\(([0-9.]+) %\).*?; "
    r"(controlled|did not control: [^;]*)"
)
RECEIVE_SEND = re.compile(r"receive->send p50 (\d+) us, p99 (\d+) us, max (\d+) us")
PREFLIGHT = re.compile(r"preflight: (.*holds here; arming|ARMING ANYWAY.*|refused to arm.*)$")
PREFLIGHT_LATE = re.compile(r"preflight: late ([0-9.]+) % of control periods")
FLOOR = re.compile(r"\[under_load\] run .*host floor \(1 ms sleep overshoot\) .*?p99 (\d+) us")
EMULATOR_STATUS = '{"link": "canopen"'
WHY = re.compile(r"error|refus|Traceback|did not|cannot|fault", re.IGNORECASE)


@dataclass
class Run:
    """One finished ``smm-launch`` run: its exit code, output lines and wall time."""

    label: str
    code: int
    lines: list[str]
    wall_s: float

    def first(self, pattern: re.Pattern[str]) -> re.Match[str] | None:
        """The first match of ``pattern`` in the output, None if none."""
        for line in self.lines:
            found = pattern.search(line)
            if found:
                return found
        return None

    @property
    def host(self) -> re.Match[str] | None:
        """The bridge's closing line: late, periods, period (ms), percent, verdict."""
        return self.first(HOST)

    @property
    def receive_send(self) -> tuple[int, int, int] | None:
        """The loop's receive -> send p50, p99, max (us); None without the direct loop's closing line."""
        found = self.first(RECEIVE_SEND)
        return None if found is None else (int(found[1]), int(found[2]), int(found[3]))

    @property
    def emulator(self) -> dict[str, Any] | None:
        """The emulated bench's end-of-run status (it prints it), None without one."""
        for line in self.lines:
            if line.startswith(EMULATOR_STATUS):
                status: dict[str, Any] = json.loads(line)
                return status
        return None

    @property
    def preflight(self) -> str:
        """What the preflight said before arming (``holds``, ``would refuse: ...``), or ``-``."""
        found = self.first(PREFLIGHT)
        late = self.first(PREFLIGHT_LATE)
        rehearsed = f" ({late[1]} % late)" if late else ""
        if found is None:
            return "-"
        if "holds here" in found[1]:
            return f"holds{rehearsed}"
        return f"would refuse{rehearsed}"

    def why(self, lines: int = 4) -> str:
        """The last lines saying why a run failed (errors, refusals), joined."""
        said = [line.strip() for line in self.lines if WHY.search(line)]
        return " | ".join(said[-lines:]) or " | ".join(line.strip() for line in self.lines[-lines:])


def start(command: Sequence[str], log: Path, *, board: bool = False) -> subprocess.Popen[bytes]:
    """``command`` in its own session, stdout and stderr to ``log``; ``board``: at the emulator's SCHED_FIFO
    priority where allowed (a bench stands for hardware, as smm-launch runs the emulated one)."""
    from smm_bringup.realtime import BOARD_PRIORITY_OFFSET, DEFAULT_HARDWARE_PRIORITY, fifo, fifo_allowed

    priority = DEFAULT_HARDWARE_PRIORITY + BOARD_PRIORITY_OFFSET
    scheduling = fifo(priority).preexec() if board and fifo_allowed(priority) else None
    with log.open("wb") as out:
        return subprocess.Popen(
            list(command),
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            preexec_fn=scheduling,  # noqa: PLW1509
        )


def finish(process: subprocess.Popen[bytes], log: Path, label: str, started: float, timeout_s: float) -> Run:
    """Waits for ``process`` (SIGINT, then SIGKILL of its session past ``timeout_s``); the run."""
    try:
        code = process.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        process.send_signal(signal.SIGINT)
        try:
            code = process.wait(timeout=60.0)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            code = process.wait()
    lines = log.read_text(errors="replace").splitlines()
    return Run(label, code, lines, time.monotonic() - started)


def launch(
    label: str,
    options: Sequence[str],
    log: Path,
    *,
    prefix: Sequence[str] = (),
    timeout_s: float = 600.0,
    until: Callable[[], bool] | None = None,
) -> Run:
    """``smm-launch --plant hardware --link canopen OPTIONS`` (after ``prefix``: a load), to its end.

    Ended as a person ends it (SIGINT) once ``until`` (polled every 0.2 s) is true, or after ``timeout_s``.
    A run with ``--duration`` ends itself, also at a fault before it (the bridge's exit 3).
    """
    command = [*prefix, *LAUNCH, *options]
    shown = " ".join(command[len(prefix) + 3 :])
    print(f"$ smm-launch {shown}{' (beside busy processes)' if prefix else ''}", flush=True)
    started = time.monotonic()
    process = start(command, log)
    while process.poll() is None and time.monotonic() - started < timeout_s:
        if until is not None and until():
            break
        time.sleep(0.2)
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    return finish(process, log, label, started, 60.0)


def tracking_rms(bag: Path, end_s: float, start_s: float = 0.0) -> tuple[float, float] | str:
    """Tracking RMS (rad) alpha, beta over [``start_s``, ``end_s``) of the run in ``bag``; else why not."""
    command = [sys.executable, "-m", "smm_bag.cli", "analyze", "--json", "--quiet"]
    command += ["--start", f"{start_s:g}", "--end", f"{end_s:g}", str(bag)]
    if not bag.exists():
        return f"no bag at {bag}"
    done = subprocess.run(command, capture_output=True, text=True, check=False, timeout=600)
    if done.returncode != 0:
        return f"smm-bag analyze exit {done.returncode}: {(done.stdout + done.stderr).strip()[-300:]}"
    document = json.loads(done.stdout)
    runs = [controllers for key, controllers in document.items() if key != "meta"]
    figures = next(iter(runs[0].values()))
    return float(figures["alpha"]["RMS"]), float(figures["beta"]["RMS"])


def uptime() -> str:
    """``uptime``'s line (the load average of a shared machine)."""
    return subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()


@contextmanager
def workdir(keep: Path | None, prefix: str) -> Iterator[Path]:
    """``keep`` (created) if given, else a temporary folder removed at the end."""
    if keep is not None:
        keep.mkdir(parents=True, exist_ok=True)
        yield keep.resolve()
        return
    with tempfile.TemporaryDirectory(prefix=prefix) as tmp:
        yield Path(tmp)
