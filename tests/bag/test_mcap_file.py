"""smm_bag.mcap_file: a bag read once leaves none of its pages mapped (bounded memory for long bags)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from bag.bag_helpers import MAKERS, T0
from smm_bag.reader import BagReader
from smm_bag.writer import BagWriter, WriterOptions

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/smaps")


def _resident_kib(path: Path) -> int:
    """Resident KiB of this process's mappings of ``path`` (smaps ``Rss``)."""
    total, current = 0, None
    with open("/proc/self/smaps") as smaps:
        for line in smaps:
            parts = line.split()
            if "-" in parts[0] and len(parts) >= 5:
                current = parts[5] if len(parts) > 5 else None
            elif parts[0] == "Rss:" and current == str(path):
                total += int(parts[1])
    return total


def test_a_bag_read_once_keeps_no_chunk_or_message_index_mapped(tmp_path: Path) -> None:
    bag = tmp_path / "chunks"
    steps = 6000
    with BagWriter(bag, WriterOptions(chunk_size=16 * 1024)) as writer:  # hundreds of chunks, each followed
        for topic in MAKERS:  # by its message indexes (16 bytes per message)
            kind = "sensor_msgs/msg/JointState" if "joint" in topic else "std_msgs/msg/Float64MultiArray"
            writer.create_topic(topic, kind)
        for k in range(steps):
            for topic in MAKERS:
                writer.write(topic, MAKERS[topic](k), T0 + k * 1_000_000)
    (file,) = sorted(bag.glob("*.mcap"))
    size_kib = file.stat().st_size // 1024
    with BagReader(bag) as reader:
        count = sum(1 for _ in reader.raw_messages(MAKERS))
        resident = _resident_kib(file)
    assert count == steps * len(MAKERS)
    assert size_kib > 2000
    # what stays is the summary read at open and the fault-around of the last block, not the file
    assert resident <= 256, (resident, size_kib)
