"""The independent bench as a process: ``python run.py GROUP PORT DURATION_S STATUS_FILE`` (until SIGTERM).

Writes ``STATUS_FILE`` ({"live_syncs": N}) when its duration of live SYNCs is done; from then on it is
silent (a lockstep run halts). The udp_multicast group is opened only over loopback.
"""

from __future__ import annotations

import json
import signal
import sys
import threading
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from smm_hw_bridge.can_multicast import loopback_multicast_bus

from bench import IndependentBench


def main(argv: list[str]) -> int:
    group, port, duration_s, status = argv[0], int(argv[1]), float(argv[2]), Path(argv[3])
    bench = IndependentBench(loopback_multicast_bus(group, port), duration_syncs=round(duration_s * 1000))
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    print(f"independent bench: valves 21, 22, encoders 31, 32 on {group}:{port}", flush=True)
    while not stop.wait(0.05):
        if bench.done.is_set() and not status.exists():
            status.write_text(json.dumps({"live_syncs": bench.live_syncs}))
            print(f"independent bench: {bench.live_syncs} live SYNCs done", flush=True)
    bench.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
