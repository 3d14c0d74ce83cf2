"""What an xdist worker's tests see, one JSON file per test: run only by tests/test_xdist_workers.py."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import can
import pytest
from netns_exec import interface_names, netns_inode  # type: ignore[import-not-found]
from smm_hw_bridge.can_multicast import loopback_multicast_bus

OUT = "SMM_XDIST_PROBE_OUT"
"""The environment variable naming the folder the records go to."""

GROUP, PORT = "239.74.163.2", 43120
"""python-can's udp_multicast group (the emulated CAN bus's) and a port: the same in every worker."""


def _multicast_round_trip(turn: int) -> list[int]:
    """The data of a frame sent on GROUP:PORT as another bus of this process received it ([] if none)."""
    sender, receiver = loopback_multicast_bus(GROUP, PORT), loopback_multicast_bus(GROUP, PORT)
    try:
        sender.send(can.Message(arbitration_id=0x181, data=[turn], is_extended_id=False))
        frame = receiver.recv(10.0)
        return [] if frame is None else list(frame.data)
    finally:
        sender.shutdown()
        receiver.shutdown()


@pytest.mark.parametrize("turn", range(3))
def test_record_what_a_worker_sees(ros_domain_id: int, turn: int) -> None:
    child = "import os; print(os.stat('/proc/self/ns/net').st_ino)"
    started = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True, check=True)
    seen = {
        "worker": os.environ["PYTEST_XDIST_WORKER"],
        "domain_id": ros_domain_id,
        "netns": netns_inode(),
        "process_netns": netns_inode("self"),
        "started_process_netns": int(started.stdout),
        "controller_netns": netns_inode(os.getppid()),
        "interfaces": interface_names(),
        "multicast": _multicast_round_trip(turn),
        "turn": turn,
    }
    Path(os.environ[OUT], f"{seen['worker']}-{turn}.json").write_text(json.dumps(seen))
