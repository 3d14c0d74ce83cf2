"""The writer's chunk indexes, held until the summary, cost their records' bytes a chunk, not a message's."""

from __future__ import annotations

import gc
import io
import tracemalloc
from pathlib import Path

from bag.bag_helpers import T0, joint_state, torque
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.records import ChunkIndex
from mcap.writer import CompressionType, Writer
from smm_bag.chunk_index import pack_chunk_indexes
from smm_bag.writer import BagWriter, WriterOptions

TOPICS = {
    "/smm/joint_states": ("sensor_msgs/msg/JointState", joint_state),
    "/smm/torque_command": ("std_msgs/msg/Float64MultiArray", torque),
    "/smm/reference": ("std_msgs/msg/Float64MultiArray", torque),
    "/smm/controller_internals": ("std_msgs/msg/Float64MultiArray", torque),
    "/smm/hw_bridge_internals": ("std_msgs/msg/Float64MultiArray", torque),
}
CHUNK_INDEX_RECORD = 9 + 8 * 4 + 4 + 8 + 4 + 8 * 2
"""Bytes of a Chunk Index record without its message index offsets (10 bytes per channel in the chunk)."""


def _mcap_bytes(pack: bool, messages: list[int], flush_after: set[int]) -> bytes:
    """An MCAP file written by mcap's own Writer, its chunk indexes packed or not."""
    buffer = io.BytesIO()
    writer = Writer(buffer, chunk_size=2048, compression=CompressionType.NONE, enable_data_crcs=True)
    if pack:
        assert pack_chunk_indexes(writer)
    writer.start(profile="ros2", library="test")
    schema = writer.register_schema(name="std_msgs/msg/Float64MultiArray", encoding="ros2msg", data=b"x")
    channels = [
        writer.register_channel(topic=f"/t{i}", message_encoding="cdr", schema_id=schema) for i in (0, 1, 2)
    ]
    for number, size in enumerate(messages):
        writer.add_message(
            channel_id=channels[number % 3], log_time=number, data=bytes(size), publish_time=number
        )
        if number in flush_after:
            writer.flush()
    writer.finish()
    return buffer.getvalue()


@settings(max_examples=30, deadline=None)
@given(
    messages=st.lists(st.integers(0, 600), max_size=200),
    flush_after=st.sets(st.integers(0, 199), max_size=40),
)
def test_packed_indexes_write_the_same_file_as_mcap(messages: list[int], flush_after: set[int]) -> None:
    packed = _mcap_bytes(True, messages, flush_after)
    assert packed == _mcap_bytes(False, messages, flush_after)
    reader = make_reader(io.BytesIO(packed))
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    assert len(summary.chunk_indexes) == summary.statistics.chunk_count
    assert sum(1 for _ in reader.iter_messages()) == len(messages)


def test_a_writer_that_has_indexed_a_chunk_or_is_not_mcaps_is_left_alone() -> None:
    writer = Writer(io.BytesIO(), compression=CompressionType.NONE)
    writer.start()
    channel = writer.register_channel(topic="/t", message_encoding="cdr", schema_id=0)
    writer.add_message(channel_id=channel, log_time=1, data=b"x", publish_time=1)
    writer.flush()
    assert not pack_chunk_indexes(writer)  # its first index would be lost from the summary
    assert not pack_chunk_indexes(object())  # type: ignore[arg-type]


def _write_chunks(writer: BagWriter, chunks: int, messages_per_chunk: int, step: int = 0) -> int:
    """``chunks`` chunks of ``messages_per_chunk`` steps of every topic (a flush after each: a chunk)."""
    for _ in range(chunks):
        for _ in range(messages_per_chunk):
            for topic, (_, make) in TOPICS.items():
                writer.write(topic, make(step), T0 + step * 1_000_000)
            step += 1
        writer.flush()
    return step


def _open_writer(path: Path) -> BagWriter:
    writer = BagWriter(path, WriterOptions())
    for topic, (type_name, _) in TOPICS.items():
        writer.create_topic(topic, type_name)
    return writer


def test_the_open_files_index_holds_no_object_per_chunk(tmp_path: Path) -> None:
    with _open_writer(tmp_path / "bag") as writer:
        _write_chunks(writer, chunks=50, messages_per_chunk=3)
        gc.collect()
        # type(), not isinstance(): some objects (canopen's unset network) raise on __class__
        assert sum(type(held) is ChunkIndex for held in gc.get_objects()) == 0  # mcap's own: 50
    summary = make_reader((tmp_path / "bag" / "bag_0.mcap").open("rb")).get_summary()
    assert summary is not None and len(summary.chunk_indexes) == 50  # every chunk still in the summary


def _growth_per_chunk(path: Path, messages_per_chunk: int, chunks: int = 200) -> float:
    """Bytes the bag writer holds more after ``chunks`` more chunks (traced Python memory), per chunk."""
    with _open_writer(path) as writer:
        step = _write_chunks(writer, 20, messages_per_chunk)
        gc.collect()
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            _write_chunks(writer, chunks, messages_per_chunk, step)
            gc.collect()
            after = tracemalloc.get_traced_memory()[0]
        finally:
            tracemalloc.stop()
    return (after - before) / chunks


def test_the_open_files_index_grows_by_its_records_per_chunk_not_per_message(tmp_path: Path) -> None:
    record = CHUNK_INDEX_RECORD + 10 * len(TOPICS)
    few = _growth_per_chunk(tmp_path / "few", messages_per_chunk=2)
    many = _growth_per_chunk(tmp_path / "many", messages_per_chunk=50)
    # The record and the buffer's slack measure 140 to 270 bytes a chunk here; mcap's ChunkIndex objects
    # 750 to 1000. A cost per message would show in `many` (250 messages a chunk: 2 bytes each is 500).
    assert 0 < few <= 4 * record, f"{few:.0f} bytes per chunk, record {record}"
    assert 0 < many <= 4 * record, f"{many:.0f} bytes per chunk, record {record}"
