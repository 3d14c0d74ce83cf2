"""What the GIL does to the direct loop's I/O thread, and what the switch interval does about it.

Figures, not pass/fail (``make bench``); no ROS, loopback UDP only. A partner process (its own GIL) plays
the board: it sends a datagram every 1 ms and times the answer (round trip, us). This process plays the
direct loop: an I/O thread blocks in ``recv`` and answers at once. Beside it, a second thread stands for
the ROS side of the process (executor callbacks, diagnostics): bursts of pure-Python work. While that
thread holds the GIL, a datagram that arrived waits until the holder gives the GIL up, which CPython
forces after ``sys.getswitchinterval()`` (5 ms by default). Rows: no second thread; then the second
thread at switch intervals 5 ms (Python's default), 1 ms, 0.5 ms (the direct loop's default,
``loop.switch_interval``) and 0.1 ms.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

SECONDS = 4.0
PERIOD_NS = 1_000_000
BURST_S = 0.004
"""Length of each burst of the competing thread (s): a long callback, e.g. building diagnostics."""
PAUSE_S = 0.002


def partner(port: int, seconds: float) -> None:
    """The board: one datagram per period to 127.0.0.1:``port``, round trips printed as one line of us."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.settimeout(0.5)
        trips: list[int] = []
        deadline = time.monotonic_ns()
        end = deadline + int(seconds * 1e9)
        while deadline < end:
            start = time.monotonic_ns()
            sock.sendto(b"x" * 72, ("127.0.0.1", port))
            try:
                sock.recv(64)
                trips.append(time.monotonic_ns() - start)
            except TimeoutError:
                pass
            deadline += PERIOD_NS
            pause = deadline - time.monotonic_ns()
            if pause > 0:
                time.sleep(pause / 1e9)
    print(" ".join(str(t // 1000) for t in trips), flush=True)


def run(switch_interval: float | None) -> np.ndarray:
    """Round trips (us) seen by the partner; ``switch_interval`` None: no competing thread."""
    sys.setswitchinterval(switch_interval or 0.005)
    stop = threading.Event()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(0.2)
        port = sock.getsockname()[1]

        def answer() -> None:
            while not stop.is_set():
                try:
                    data, source = sock.recvfrom(128)
                except TimeoutError:
                    continue
                sock.sendto(data[:40], source)

        def compete() -> None:
            while not stop.is_set():
                end = time.perf_counter() + BURST_S
                total = 0
                while time.perf_counter() < end:
                    total += sum(range(200))
                time.sleep(PAUSE_S)

        threads = [threading.Thread(target=answer, daemon=True)]
        if switch_interval is not None:
            threads.append(threading.Thread(target=compete, daemon=True))
        for thread in threads:
            thread.start()
        board = subprocess.run(
            [sys.executable, str(Path(__file__).resolve()), "--partner", str(port), str(SECONDS)],
            capture_output=True,
            text=True,
            check=True,
        )
        stop.set()
        for thread in threads:
            thread.join(1.0)
    return np.asarray([int(v) for v in board.stdout.split()], dtype=np.float64)


def main(argv: list[str]) -> int:
    if argv[:1] == ["--partner"]:
        partner(int(argv[1]), float(argv[2]))
        return 0
    print(f"UDP round trip board -> I/O thread -> board, 1 kHz, {SECONDS:.0f} s per row (us):")
    for label, interval in (
        ("I/O thread alone", None),
        ("+ busy thread, switch interval 5 ms (Python's default)", 0.005),
        ("+ busy thread, switch interval 1 ms", 0.001),
        ("+ busy thread, switch interval 0.5 ms (direct loop default)", 0.0005),
        ("+ busy thread, switch interval 0.1 ms", 0.0001),
    ):
        trips = run(interval)
        late = 100.0 * float(np.mean(trips > PERIOD_NS / 1e3)) if trips.size else float("nan")
        print(
            f"  {label:60s} p50 {np.percentile(trips, 50):7.0f}  p99 {np.percentile(trips, 99):7.0f}  "
            f"max {trips.max():7.0f}  > 1 period {late:5.1f} %"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
