"""Pieces of the long-run tools (record_hours.py, soak.py): ``smm-launch`` watched, RSS sampled, bags checked.

Figures only: nothing here decides from the machine's speed. docs/SOAK.md explains what is measured.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from smm_bag.cdr import stamp_of
from smm_bag.errors import BagError
from smm_bag.loss import loss_from_json
from smm_bag.reader import BagReader

__all__ = [
    "WARMUP_S",
    "BagCheck",
    "LaunchedGraph",
    "RssSeries",
    "check_bag",
    "dump_json",
    "rss_kib",
    "slope_per_hour",
    "verdict",
]

WARMUP_S = 60.0
"""Seconds of a run left out of the RSS slopes (imports, first allocations)."""
PLATEAU_S = 600.0
"""The RSS at this many seconds is the reference of a long run's growth (the middleware's and the allocator's
pools have reached their working size by then: docs/SOAK.md, "The recorder's memory")."""

_STARTED = re.compile(r"\[smm-launch\] (?:started|respawned) (\S+) \(pid (\d+)")
_PAGE_KIB = os.sysconf("SC_PAGE_SIZE") // 1024


def rss_kib(pid: int) -> int | None:
    """Resident set size of ``pid`` (KiB) from /proc, None once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/statm").read_text().split()
    except OSError:
        return None
    return int(fields[1]) * _PAGE_KIB


def slope_per_hour(times_s: Sequence[float], values: Sequence[float]) -> float:
    """Least-squares slope of ``values`` against ``times_s``, per hour (0 with fewer than 3 points)."""
    count = len(times_s)
    if count < 3:
        return 0.0
    mean_t = sum(times_s) / count
    mean_v = sum(values) / count
    spread = sum((t - mean_t) ** 2 for t in times_s)
    if spread == 0:
        return 0.0
    return 3600.0 * sum((t - mean_t) * (v - mean_v) for t, v in zip(times_s, values, strict=True)) / spread


@dataclass
class RssSeries:
    """RSS samples of one process (one pid; a respawned process starts a new series)."""

    name: str
    pid: int
    times_s: list[float] = field(default_factory=list)
    kib: list[int] = field(default_factory=list)

    def slope_mib_per_hour(self, warmup_s: float) -> float:
        """RSS growth (MiB/h) fitted after the first ``warmup_s`` seconds of this series."""
        if not self.times_s:
            return 0.0
        start = self.times_s[0] + warmup_s
        points = [(t, k / 1024) for t, k in zip(self.times_s, self.kib, strict=True) if t >= start]
        return slope_per_hour([t for t, _ in points], [v for _, v in points])

    def kib_at(self, seconds: float) -> int | None:
        """The first sample at least ``seconds`` after this series' first (KiB); None if it ended before."""
        if not self.times_s:
            return None
        start = self.times_s[0] + seconds
        return next((k for t, k in zip(self.times_s, self.kib, strict=True) if t >= start), None)

    def summary(self, warmup_s: float) -> str:
        """``name pid: first -> last MiB, slope S MiB/h[, end - 10 min D MiB]`` (one line)."""
        if not self.kib:
            return f"{self.name} (pid {self.pid}): no sample"
        span = (self.times_s[-1] - self.times_s[0]) / 60
        at_10 = self.kib_at(PLATEAU_S) if span * 60 > PLATEAU_S else None
        since = "" if at_10 is None else f", end - 10 min {(self.kib[-1] - at_10) / 1024:+.1f} MiB"
        return (
            f"{self.name} (pid {self.pid}): RSS {self.kib[0] / 1024:.1f} -> {self.kib[-1] / 1024:.1f} MiB "
            f"(max {max(self.kib) / 1024:.1f}) over {span:.1f} min, slope after {warmup_s:g} s warm-up "
            f"{self.slope_mib_per_hour(warmup_s):+.2f} MiB/h{since}"
        )


class LaunchedGraph:
    """``smm-launch ARGS`` in its own session, its output teed to ``log``; the nodes' pids from its lines.

    Args:
        arguments: ``smm-launch`` arguments.
        log: File that receives every line of the launcher and its nodes.
        env: Extra environment (the discovery range stays on this machine).
    """

    def __init__(self, arguments: Sequence[str], log: Path, env: dict[str, str] | None = None) -> None:
        environment = dict(os.environ)
        environment.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        environment["PYTHONUNBUFFERED"] = "1"
        environment.update(env or {})
        launcher = Path(sys.executable).parent / "smm-launch"
        self.started_s = time.monotonic()
        self.log_path = log
        self._log = log.open("w")
        self.pids: dict[str, int] = {}
        self.series: list[RssSeries] = []
        self.tracebacks: list[str] = []
        self.lines: list[tuple[float, str]] = []
        self._lock = threading.Lock()
        self.process = subprocess.Popen(
            [str(launcher), *arguments],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=environment,
            start_new_session=True,
            text=True,
            bufsize=1,
        )
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def elapsed(self) -> float:
        """Seconds since the launcher started."""
        return time.monotonic() - self.started_s

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            now = self.elapsed()
            self._log.write(f"{now:10.3f} {line}")
            self._log.flush()
            with self._lock:
                self.lines.append((now, line.rstrip("\n")))
                if len(self.lines) > 20_000:
                    del self.lines[:10_000]
                if "Traceback (most recent call last)" in line:
                    self.tracebacks.append(f"{now:.1f} s")
                match = _STARTED.search(line)
                if match:
                    name, pid = match.group(1), int(match.group(2))
                    self.pids[name] = pid
                    self.series.append(RssSeries(name, pid))

    def lines_since(self, start_s: float) -> list[str]:
        """Output lines that arrived at or after ``start_s`` (launcher time)."""
        with self._lock:
            return [line for when, line in self.lines if when >= start_s]

    def sample(self) -> None:
        """One RSS sample of every live node process."""
        now = self.elapsed()
        with self._lock:
            current = {series.pid: series for series in self.series}
        for series in current.values():
            value = rss_kib(series.pid)
            if value is not None:
                series.times_s.append(now)
                series.kib.append(value)

    def wait_for(self, name: str, timeout_s: float) -> int | None:
        """The pid of node ``name`` once started (None if the launcher ends or ``timeout_s`` passes)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and self.process.poll() is None:
            with self._lock:
                if name in self.pids:
                    return self.pids[name]
            time.sleep(0.05)
        return None

    def stop(self, timeout_s: float = 60.0) -> int:
        """SIGINT to the launcher (it stops its nodes, the recorder last); its exit code."""
        if self.process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()
        self._reader.join(timeout=10)
        self._log.close()
        return int(self.process.returncode)


@dataclass
class BagCheck:
    """What a recorded bag holds: files, counts, the recorder's loss report, stamp continuity."""

    files: list[tuple[str, int, int]]
    """(name, bytes, messages) per storage file."""
    topic_counts: dict[str, int]
    loss: dict[str, dict[str, int]]
    stamps: dict[str, tuple[int, int, int]]
    """topic -> (messages, samples missing in forward steps, steps back or repeated stamps)."""
    error: str | None = None

    @property
    def lost(self) -> int:
        """Messages the recorder received and did not write."""
        return sum(counters.get("lost", 0) for counters in self.loss.values())

    @property
    def missing(self) -> int:
        """Samples missing in the stamps of the checked topics (re-read from the files)."""
        return sum(missing for _, missing, _ in self.stamps.values())

    def lines(self) -> list[str]:
        """A printable report."""
        if self.error is not None:
            return [f"bag: UNREADABLE: {self.error}"]
        total = sum(count for _, _, count in self.files)
        size = sum(size for _, size, _ in self.files)
        out = [f"bag: {len(self.files)} files, {size / 2**20:.1f} MiB, {total} messages"]
        out += [f"  {name}: {size / 2**20:.1f} MiB, {count} messages" for name, size, count in self.files]
        for topic, (count, missing, backwards) in sorted(self.stamps.items()):
            out.append(
                f"  {topic}: {count} stamps, {missing} samples missing, {backwards} steps back or repeats"
            )
        out.append(f"  recorder loss report: {self.lost} received and not written")
        return out


def check_bag(path: Path, stamped: Sequence[str], period_ns: int) -> BagCheck:
    """Opens the bag (metadata.yaml's counts checked against every file), re-reads the stamps of ``stamped``.

    A bag that will not open is reported in ``error``, never raised.
    """
    try:
        with BagReader(path) as reader:
            metadata = reader.metadata
            counts = {info.name: info.message_count for info in metadata.topics}
            files = [
                (info.path, (path / info.path).stat().st_size, info.message_count) for info in metadata.files
            ]
            loss = {
                topic: dict(counters)
                for topic, counters in loss_from_json(metadata.custom_data.get("smm.loss", "{}")).items()
            }
            stamps: dict[str, tuple[int, int, int]] = {}
            for topic in stamped:
                if topic not in counts:
                    continue
                type_name = reader.topics[topic]
                count = missing = backwards = 0
                last: int | None = None
                for _, _, data in reader.raw_messages([topic]):
                    stamp = stamp_of(type_name, data)
                    count += 1
                    if stamp is None:
                        continue
                    if last is not None:
                        step = stamp - last
                        if step <= 0:
                            backwards += 1  # a resent measurement, or stamps that start anew (new host)
                        elif step > period_ns * 3 // 2:
                            missing += round(step / period_ns) - 1
                    last = stamp
                stamps[topic] = (count, missing, backwards)
    except (BagError, OSError, ValueError) as error:
        return BagCheck([], {}, {}, {}, error=f"{type(error).__name__}: {error}")
    return BagCheck(files, counts, loss, stamps)


def dump_json(path: Path, data: object) -> None:
    """Writes ``data`` as indented JSON."""
    path.write_text(json.dumps(data, indent=2, default=str))


def verdict(failures: Sequence[str]) -> int:
    """Prints the run's result line; the exit code: 0 when no criterion failed, else 1."""
    print("result: " + ("PASS" if not failures else "FAIL: " + "; ".join(failures)))
    return 0 if not failures else 1
