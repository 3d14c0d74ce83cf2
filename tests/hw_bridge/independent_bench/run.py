"""The independent bench as a process: ``python run.py GROUP PORT DURATION_S STATUS_FILE [--clock C]
[--keep-answering] [--no-receive-deadline]`` (until SIGTERM or SIGINT).

Writes ``STATUS_FILE`` (its figures, JSON) when ``DURATION_S`` of live plant time is done; from then on it is
silent (a lockstep run halts), or with ``--keep-answering`` (real time) it answers on. At exit it prints its
figures (``independent bench: {...}``). ``--clock``: ``sync`` (default: the cycle period 0x1006 times the
SYNC counter's periods) or ``wall``. The udp_multicast group is opened only over loopback.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from smm_hw_bridge.can_multicast import loopback_multicast_bus

from bench import CLOCKS, IndependentBench


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="run.py", description=__doc__.splitlines()[0])
    parser.add_argument("group")
    parser.add_argument("port", type=int)
    parser.add_argument("duration_s", type=float, help="live plant seconds (0: no end)")
    parser.add_argument("status", type=Path)
    parser.add_argument("--clock", choices=CLOCKS, default="sync")
    parser.add_argument("--keep-answering", action="store_true", help="answer on after DURATION_S")
    parser.add_argument("--no-receive-deadline", action="store_true", help="the valves' deadline unwatched")
    arguments = parser.parse_args(argv)
    bench = IndependentBench(
        loopback_multicast_bus(arguments.group, arguments.port),
        duration_s=arguments.duration_s,
        clock=arguments.clock,
        keep_answering=arguments.keep_answering,
        receive_deadline=not arguments.no_receive_deadline,
    )
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    where = f"{arguments.group}:{arguments.port}"
    print(
        f"independent bench: valves 21, 22, encoders 31, 32 on {where}, clock {arguments.clock}", flush=True
    )
    status: Path = arguments.status
    while not stop.wait(0.05):
        if bench.done.is_set() and not status.exists():
            status.write_text(json.dumps(bench.figures()))
            print(f"independent bench: {bench.live_syncs} live SYNCs done", flush=True)
    bench.close()
    print(f"independent bench: {json.dumps(bench.figures())}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
