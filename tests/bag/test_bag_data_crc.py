"""The writer's data-section CRC and ``smm-bag repair`` checking it: a byte changed outside every chunk."""

from __future__ import annotations

import io
import shutil
import struct
import zlib
from collections.abc import Callable
from pathlib import Path

import pytest
from bag.bag_helpers import T0, joint_state, torque
from mcap.reader import make_reader
from mcap.stream_reader import CRCValidationError, StreamReader
from smm_bag.commands import repair
from smm_bag.writer import BagWriter, WriterOptions

from smm_bag import BagReader, read_metadata

_DATA_END = 9 + 4  # opcode, length, data_section_crc (u32)
_FOOTER_AT = 8 + 9 + 20  # from the end: magic, then the Footer record


def _bag(path: Path, options: WriterOptions | None = None) -> Path:
    with BagWriter(path, options or WriterOptions(chunk_size=4096)) as writer:
        writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState")
        writer.create_topic("/smm/torque_command", "std_msgs/msg/Float64MultiArray")
        for k in range(300):
            writer.write("/smm/joint_states", joint_state(k), T0 + k * 1_000_000)
            writer.write("/smm/torque_command", torque(k), T0 + k * 1_000_000 + 1)
    return path


def _data_end(data: bytes) -> tuple[int, int]:
    """Offset of the Data End record (just before the summary the Footer points at) and its CRC."""
    summary_start = struct.unpack_from("<Q", data, len(data) - _FOOTER_AT + 9)[0]
    at = summary_start - _DATA_END
    opcode, length, crc = struct.unpack_from("<BQI", data, at)
    assert (opcode, length) == (0x0F, 4), "no Data End record before the summary"
    return at, crc


def _mcap_checks(data: bytes) -> None:
    """Reads every record with the mcap library validating the chunk and data-section CRCs (raises if not)."""
    for _ in StreamReader(io.BytesIO(data), validate_crcs=True).records:
        pass


@pytest.mark.parametrize(
    "options",
    [
        WriterOptions(chunk_size=4096),
        WriterOptions(chunk_size=4096, compression="zstd"),
        WriterOptions(chunk_size=4096, max_size_bytes=64 * 1024),
    ],
    ids=["plain", "zstd", "split"],
)
def test_every_written_file_has_a_data_section_crc_over_every_byte_before_data_end(
    tmp_path: Path, options: WriterOptions
) -> None:
    bag = _bag(tmp_path / "bag", options)
    files = [bag / name for name in read_metadata(bag).relative_file_paths]
    assert len(files) >= (2 if options.max_size_bytes else 1)
    for path in files:
        data = path.read_bytes()
        at, crc = _data_end(data)
        assert crc != 0
        assert crc == zlib.crc32(data[:at])
        _mcap_checks(data)


def _flip_header(data: bytearray) -> None:
    profile = struct.unpack_from("<I", data, 8 + 9)[0]
    data[8 + 9 + 4 + profile + 4 + 3] ^= 0x01  # a character of the Header's library string


def _flip_metadata(data: bytearray) -> None:
    with io.BytesIO(bytes(data)) as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    first = summary.metadata_indexes[0]  # the rosbag2 record written at open: a top-level record
    assert first.name == "rosbag2"
    chunks = [(c.chunk_start_offset, c.chunk_start_offset + c.chunk_length) for c in summary.chunk_indexes]
    at = first.offset + first.length // 2  # inside its serialized_metadata text
    assert not any(start <= at < end for start, end in chunks)
    data[at] ^= 0x01


def _flip_crc(data: bytearray) -> None:
    at, _ = _data_end(bytes(data))
    data[at + 9] ^= 0x01  # the CRC itself


@pytest.mark.parametrize(
    "flip", [_flip_header, _flip_metadata, _flip_crc], ids=["header", "metadata record", "the crc"]
)
def test_a_byte_changed_outside_every_chunk_makes_the_file_not_intact_and_says_why(
    tmp_path: Path, flip: Callable[[bytearray], None]
) -> None:
    bag = _bag(tmp_path / "bag")
    untouched = shutil.copytree(bag, tmp_path / "untouched")
    path = bag / "bag_0.mcap"
    data = bytearray(path.read_bytes())
    flip(data)
    path.write_bytes(bytes(data))
    with pytest.raises(CRCValidationError):  # the mcap library sees it too
        _mcap_checks(bytes(data))

    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0
    text = out.getvalue()
    assert "intact" not in text
    assert "bag_0.mcap: damaged: data section CRC mismatch (a byte no chunk CRC covers changed" in text
    assert "kept 600 messages" in text and "lost 0 chunks, no message" in text  # every chunk checks
    assert (bag / "bag_0.mcap.damaged").read_bytes() == data
    with BagReader(bag) as reader:
        assert sum(1 for _ in reader.messages()) == 600
    again = io.StringIO()
    assert repair(bag, stdout=again, stderr=io.StringIO()) == 0
    assert "bag_0.mcap: intact (600 messages" in again.getvalue()
    assert "data section CRC checks" in again.getvalue()

    before = {p.name: p.read_bytes() for p in untouched.iterdir()}  # the same bag, untouched: intact
    clean = io.StringIO()
    assert repair(untouched, stdout=clean, stderr=io.StringIO()) == 0
    assert "bag_0.mcap: intact (600 messages" in clean.getvalue()
    assert "data section CRC checks" in clean.getvalue()
    assert {p.name: p.read_bytes() for p in untouched.iterdir()} == before


def _zero_data_crc(path: Path) -> bytes:
    data = bytearray(path.read_bytes())
    at, _ = _data_end(bytes(data))
    data[at + 9 : at + 13] = bytes(4)  # 0: "not computed" (older bags, other writers)
    path.write_bytes(bytes(data))
    return bytes(data)


def test_a_bag_without_data_section_crc_is_intact_when_everything_else_checks(tmp_path: Path) -> None:
    bag = _bag(tmp_path / "bag", WriterOptions(chunk_size=4096, max_size_bytes=64 * 1024))
    names = read_metadata(bag).relative_file_paths
    assert len(names) >= 2
    for name in names:
        _mcap_checks(_zero_data_crc(bag / name))  # the mcap library does not check a CRC of 0 either
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0
    lines = out.getvalue().splitlines()
    for name in names:
        line = next(line for line in lines if line.startswith(f"{name}: "))
        assert line.startswith(f"{name}: intact (") and "no data section CRC written" in line
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before


def test_without_data_section_crc_the_same_change_in_a_metadata_record_goes_unseen(tmp_path: Path) -> None:
    """What the data CRC adds: with a CRC of 0 the change above is covered by no CRC (docs/BAGS.md)."""
    bag = _bag(tmp_path / "bag")
    path = bag / "bag_0.mcap"
    _zero_data_crc(path)
    data = bytearray(path.read_bytes())
    _flip_metadata(data)
    path.write_bytes(bytes(data))
    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0
    assert "bag_0.mcap: intact (600 messages" in out.getvalue()
