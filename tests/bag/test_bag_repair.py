"""smm-bag repair after a crash: a killed writer's bag is rebuilt with everything flushed before the kill."""

from __future__ import annotations

import io
import os
import random
import shutil
import signal
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from bag.bag_helpers import T0, joint_state, mcap_messages, rosbags_messages
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from smm_bag.cli import main
from smm_bag.commands import repair
from smm_bag.errors import UnsalvageableFileError
from smm_bag.exit_codes import EXIT_UNSALVAGEABLE
from smm_bag.repair import repair_bag
from smm_bag.writer import BagWriter, WriterOptions

from smm_bag import BagReader, read_metadata

_WRITER = """
import sys, time
from smm_bag.writer import BagWriter, WriterOptions
from smm_bag.cdr import encode_joint_state
writer = BagWriter(sys.argv[1], WriterOptions(flush_interval_ns=20_000_000, chunk_size=1 << 30))
writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState")
k = 0
while True:
    writer.write("/smm/joint_states", encode_joint_state(k, ["alpha", "beta"], [k, 0.0]), 10**18 + k)
    k += 1
    if writer.flushed_count >= 2000:
        print(writer.flushed_count, flush=True)
        time.sleep(60)
    if k % 200 == 0:
        print(writer.flushed_count, flush=True)
    time.sleep(0.0002)
"""


def test_sigkill_mid_run_then_repair_recovers_every_flushed_message(tmp_path: Path) -> None:
    bag = tmp_path / "killed"
    child = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(bag)], stdout=subprocess.PIPE, text=True, env=dict(os.environ)
    )
    assert child.stdout is not None
    flushed = 0
    try:
        for line in child.stdout:
            flushed = int(line)
            if flushed >= 1000:
                break
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
    assert flushed >= 1000
    report = repair_bag(bag)
    assert report.changed and report.files[0].backup == "killed_0.mcap.damaged"
    with BagReader(bag) as reader:
        recovered = reader.message_count
        stamps = [m.log_time_ns - 10**18 for m in reader.messages()]
    # Everything the writer reported as flushed before the kill is back, in order, nothing invented.
    assert recovered >= flushed
    assert stamps == list(range(recovered))
    assert len(rosbags_messages(bag)["/smm/joint_states"]) == recovered
    assert len(mcap_messages(bag)["/smm/joint_states"]) == recovered
    assert read_metadata(bag).custom_data["smm.repaired"].startswith("killed_0.mcap: truncated")


def _partial_bag(tmp_path: Path) -> tuple[Path, int]:
    bag = tmp_path / "bag"
    now = [0]
    writer = BagWriter(bag, WriterOptions(flush_interval_ns=1, chunk_size=1 << 30), clock=lambda: now[0])
    writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState")
    for k in range(300):
        now[0] += 1
        writer.write("/smm/joint_states", joint_state(k), T0 + k * 1_000_000)
    size = (bag / "bag_0.mcap").stat().st_size
    writer.close()
    return bag, size


@settings(max_examples=25, deadline=None)
@given(fraction=st.floats(0.0, 1.0))
def test_repair_of_a_file_cut_anywhere_keeps_a_readable_prefix(
    tmp_path_factory: object, fraction: float
) -> None:
    base = Path(str(tmp_path_factory.mktemp("cut")))  # type: ignore[attr-defined]
    bag, flushed_size = _partial_bag(base)
    cut = int(8 + fraction * (flushed_size - 8))
    path = bag / "bag_0.mcap"
    path.write_bytes(path.read_bytes()[:cut])
    header_end = 8 + 9 + struct.unpack_from("<Q", path.read_bytes(), 9)[0] if cut >= 17 else 17
    if cut < header_end:  # not even the header record: nothing checks, the bag is left as it was
        with pytest.raises(UnsalvageableFileError, match="nothing can be saved"):
            repair_bag(bag, backup=False)
        assert path.stat().st_size == cut
        return
    report = repair_bag(bag, backup=False)
    assert not (bag / "bag_0.mcap.damaged").exists()
    with BagReader(bag) as reader:
        times = [m.log_time_ns for m in reader.messages()]
    assert times == [T0 + k * 1_000_000 for k in range(len(times))]
    assert report.files[0].messages == len(times)


def test_garbage_file_is_unsalvageable_exit_8_left_as_it_was_and_the_rest_repaired(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    with BagWriter(bag, WriterOptions(max_duration_ns=100_000_000)) as writer:
        writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState")
        for k in range(250):
            writer.write("/smm/joint_states", joint_state(k), T0 + k * 1_000_000)
    garbage = bytes(random.Random(1).randrange(256) for _ in range(20_000))
    (bag / "bag_1.mcap").write_bytes(garbage)
    out, err = io.StringIO(), io.StringIO()
    assert repair(bag, stdout=out, stderr=err) == EXIT_UNSALVAGEABLE == 8
    assert "bag_1.mcap: unsalvageable" in out.getvalue() and "nothing can be saved" in err.getvalue()
    assert (bag / "bag_1.mcap").read_bytes() == garbage
    assert not (bag / "bag_1.mcap.damaged").exists()
    assert read_metadata(bag).relative_file_paths == ("bag_0.mcap", "bag_2.mcap")
    with BagReader(bag) as reader:  # the rest of the bag reads again
        assert reader.message_count == 250 - sum(1 for k in range(250) if 100 <= k < 200)


def test_bag_of_garbage_only_is_left_alone_with_exit_8(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap").write_bytes(b"not an MCAP file at all" * 100)
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    before = {path.name: path.read_bytes() for path in bag.iterdir()}
    assert main(["repair", str(bag)]) == EXIT_UNSALVAGEABLE
    assert {path.name: path.read_bytes() for path in bag.iterdir()} == before


def test_a_broken_chunk_crc_is_named_and_not_intact(tmp_path: Path) -> None:
    bag, _ = _partial_bag(tmp_path)
    path = bag / "bag_0.mcap"
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0x10  # inside a chunk's records: its CRC no longer checks
    path.write_bytes(bytes(data))
    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0
    text = out.getvalue()
    assert "intact" not in text and "chunk CRC mismatch" in text and "lost 1 chunks, " in text
    assert "/smm/joint_states 1)" in text  # the statistics (their CRC checks) say what was lost
    assert read_metadata(bag).message_count == 299
    assert (bag / "metadata.yaml.damaged").exists() and (bag / "bag_0.mcap.damaged").read_bytes() == data
    before = {path.name: path.read_bytes() for path in bag.iterdir()}
    again = io.StringIO()
    assert repair(bag, stdout=again, stderr=io.StringIO()) == 0  # a repaired bag is intact: nothing changes
    assert "bag_0.mcap: intact (299 messages" in again.getvalue()
    assert {path.name: path.read_bytes() for path in bag.iterdir()} == before


@pytest.mark.parametrize("summary_damaged", [False, True])
def test_records_after_damaged_framing_are_found_by_the_resynchronising_search(
    tmp_path: Path, summary_damaged: bool
) -> None:
    bag, _ = _partial_bag(tmp_path)  # one message per chunk
    path = bag / "bag_0.mcap"
    data = bytearray(path.read_bytes())
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and len(summary.chunk_indexes) == 300
    for k in (10, 200):  # two places: the chunk's length field, so the next record cannot be framed
        offset = summary.chunk_indexes[k].chunk_start_offset
        data[offset + 1 : offset + 9] = b"\xff" * 8
    footer_at = len(data) - 8 - 29
    if summary_damaged:  # the chunk index no longer checks: the search must find the chunks
        data[(footer_at + struct.unpack_from("<Q", data, footer_at + 9)[0]) // 2] ^= 0x01
        data[struct.unpack_from("<Q", data, footer_at + 9)[0] + 40] ^= 0x01
    path.write_bytes(bytes(data))
    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0
    assert ("summary CRC mismatch" in out.getvalue()) == summary_damaged
    with BagReader(bag) as reader:
        times = [m.log_time_ns for m in reader.messages()]
    # The chunks are uncompressed: reading on at the next record that checks finds the records inside the
    # two chunks whose length is damaged (each followed by a record), so every message is kept.
    assert times == [T0 + k * 1_000_000 for k in range(300)]


@pytest.mark.parametrize("summary_damaged", [False, True])
def test_channels_come_from_whichever_copy_checks(tmp_path: Path, summary_damaged: bool) -> None:
    bag, _ = _partial_bag(tmp_path)  # the first chunk holds the only in-chunk schema and channel records
    path = bag / "bag_0.mcap"
    data = bytearray(path.read_bytes())
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    first = summary.chunk_indexes[0]
    data[first.chunk_start_offset + first.chunk_length // 2] ^= 0x04  # its CRC no longer checks
    footer_at = len(data) - 8 - 29
    if summary_damaged:
        data[struct.unpack_from("<Q", data, footer_at + 9)[0] + 20] ^= 0x04
    path.write_bytes(bytes(data))
    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0
    kept = mcap_messages(bag).get("/smm/joint_states", [])
    if summary_damaged:  # no copy of the channel record checks: its messages cannot be kept, and say so
        assert kept == []
        assert "channel 1 (no channel or schema record survives) 299" in out.getvalue()
        assert "lost log time from the start to the end" in out.getvalue()
    else:  # the summary's copy checks: every message of the 299 undamaged chunks is kept
        assert [time for time, _ in kept] == [T0 + k * 1_000_000 for k in range(1, 300)]


def test_lz4_chunks_are_checked_and_kept_as_lz4(tmp_path: Path) -> None:
    bag, _ = _partial_bag(tmp_path)
    path = bag / "bag_0.mcap"
    with path.open("rb") as stream:  # the same records in lz4 chunks of 10 messages (the writer has no lz4)
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        records = list(reader.iter_messages())
    with path.open("wb") as stream:
        writer = Writer(stream, chunk_size=2000, compression=CompressionType.LZ4)
        writer.start(profile="ros2", library="test")
        for schema in summary.schemas.values():
            writer.register_schema(schema.name, schema.encoding, schema.data)
        for channel in summary.channels.values():
            writer.register_channel(
                channel.topic, channel.message_encoding, channel.schema_id, channel.metadata
            )
        for _, _, message in records:
            writer.add_message(message.channel_id, message.log_time, message.data, message.publish_time)
        writer.finish()  # type: ignore[no-untyped-call]
    data = bytearray(path.read_bytes())
    with path.open("rb") as stream:
        rewritten = make_reader(stream).get_summary()
    assert rewritten is not None
    chunks = rewritten.chunk_indexes
    assert len(chunks) > 10 and {chunk.compression for chunk in chunks} == {"lz4"}
    damaged = chunks[5]
    data[damaged.chunk_start_offset + damaged.chunk_length - 3] ^= 0x20  # inside its compressed records
    path.write_bytes(bytes(data))
    assert repair(bag, stdout=io.StringIO(), stderr=io.StringIO()) == 0
    kept = [time for time, _ in mcap_messages(bag)["/smm/joint_states"]]
    lost = {time for time in (T0 + k * 1_000_000 for k in range(300)) if time not in kept}
    assert kept == sorted(kept) and len(kept) + len(lost) == 300
    assert lost == set(range(damaged.message_start_time, damaged.message_end_time + 1, 1_000_000))
    with path.open("rb") as stream:
        repaired = make_reader(stream).get_summary()
    assert repaired is not None and {chunk.compression for chunk in repaired.chunk_indexes} == {"lz4"}


def test_repair_of_an_intact_bag_changes_nothing(tmp_path: Path) -> None:
    bag, _ = _partial_bag(tmp_path)
    before = {path.name: path.read_bytes() for path in bag.iterdir()}
    report = repair_bag(bag)
    assert not report.changed
    assert {path.name: path.read_bytes() for path in bag.iterdir()} == before


def test_repair_rebuilds_a_lost_metadata_yaml(tmp_path: Path) -> None:
    bag, _ = _partial_bag(tmp_path)
    expected = read_metadata(bag)
    (bag / "metadata.yaml").unlink()
    repair_bag(bag)
    rebuilt = read_metadata(bag)
    assert rebuilt.topics == expected.topics
    assert rebuilt.files == expected.files
    assert rebuilt.custom_data == expected.custom_data


def test_killed_split_bag_keeps_earlier_files(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    writer = BagWriter(bag, WriterOptions(max_duration_ns=100_000_000))
    writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState")
    for k in range(250):
        writer.write("/smm/joint_states", joint_state(k), T0 + k * 1_000_000)
    writer.flush()
    crashed = tmp_path / "crashed"
    shutil.copytree(bag, crashed)
    writer.close()
    report = repair_bag(crashed)
    assert [item.rebuilt for item in report.files] == [False, False, True]
    assert read_metadata(crashed).message_count == 250
    assert len(mcap_messages(crashed)["/smm/joint_states"]) == 250
