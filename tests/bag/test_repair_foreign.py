"""Repair of damaged bags of other writers' shapes (issue 29): every message a sequential read gives is kept.

The oracle is ``mcap``'s StreamReader: the messages it reads from the start of the damaged file up to the
damage, and from the first intact record after the damage (found in the undamaged original) to the end.
"""

from __future__ import annotations

import io
import struct
from collections import Counter
from pathlib import Path

import pytest
import zstandard
from bag.bag_helpers import good_bag
from bag.foreign import Key, Shape, mcap_bytes, rewrite, stream_messages
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.records import Channel
from mcap.stream_reader import StreamReader
from smm_bag.commands import repair
from smm_bag.reader import BagReader
from smm_bag.repair import repair_bag

MAGIC = b"\x89MCAP0\r\n"
DAMAGED_SHAPES = [
    Shape(chunked=False),
    Shape(chunked=False, crcs=False, statistics=False, indexes=False, summary_channels=False),
    Shape(compression="", crcs=False),
    Shape(compression="lz4"),
]


@pytest.fixture(scope="module")
def original(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return good_bag(tmp_path_factory.mktemp("original") / "run")


def _records(data: bytes) -> list[tuple[int, int, int]]:
    """``(offset, end, opcode)`` of each top-level record of an undamaged file, up to the footer."""
    found, position = [], len(MAGIC)
    while position < len(data) - len(MAGIC):
        opcode, length = struct.unpack_from("<BQ", data, position)
        found.append((position, position + 9 + length, opcode))
        position += 9 + length
    return found


def _channels(data: bytes) -> dict[int, str]:
    return {
        record.id: record.topic
        for record in StreamReader(io.BytesIO(data), validate_crcs=False).records
        if isinstance(record, Channel)
    }


def _kept(bag: Path) -> list[Key]:
    with BagReader(bag) as reader:
        return [(m.topic, m.log_time_ns, m.data) for m in reader.messages(ordered=False)]


def _oracle(original: bytes, damaged: bytes, end: int) -> list[Key]:
    """What a sequential read gives: the messages before the damage and from the first record after it."""
    channels = _channels(original)
    before = stream_messages(damaged, dict(channels))
    after_at = next((offset for offset, _, _ in _records(original) if offset >= end), None)
    if after_at is None or after_at >= len(damaged):
        return before
    after = stream_messages(MAGIC + damaged[after_at:], dict(channels))
    return before + after


def _file(bag: Path) -> Path:
    return next(bag.glob("*.mcap*"))


@pytest.mark.parametrize("shape", DAMAGED_SHAPES, ids=[shape.name for shape in DAMAGED_SHAPES])
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(0.02, 0.98))
def test_a_cut_file_keeps_every_message_the_sequential_read_gives(
    original: Path, tmp_path_factory: pytest.TempPathFactory, shape: Shape, fraction: float
) -> None:
    bag = rewrite(original, tmp_path_factory.mktemp("cut") / "copy", shape)
    path = _file(bag)
    data = path.read_bytes()
    cut = data[: int(len(data) * fraction)]
    path.write_bytes(cut)
    expected = stream_messages(cut)
    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0, out.getvalue()
    kept = _kept(bag)
    assert not Counter(expected) - Counter(kept), out.getvalue()
    assert (bag / f"{path.name}.damaged").read_bytes() == cut


@pytest.mark.parametrize("shape", DAMAGED_SHAPES, ids=[shape.name for shape in DAMAGED_SHAPES])
@pytest.mark.parametrize("where", [0.3, 0.7])
def test_framing_damage_keeps_every_message_before_and_after_it(
    original: Path, tmp_path: Path, shape: Shape, where: float
) -> None:
    bag = rewrite(original, tmp_path / "copy", shape)
    path = _file(bag)
    data = path.read_bytes()
    records = [r for r in _records(data) if r[2] in (0x05, 0x06)]  # messages or chunks
    offset, end, _ = records[int(len(records) * where)]
    damaged = bytearray(data)
    damaged[offset + 1 : offset + 9] = b"\xff" * 8  # its length: the record cannot be framed
    path.write_bytes(bytes(damaged))
    expected = _oracle(data, bytes(damaged), end)
    assert len(expected) >= 500  # the oracle reads past the damage
    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0
    assert "framing damaged" in out.getvalue()
    kept = _kept(bag)
    assert not Counter(expected) - Counter(kept), out.getvalue()
    assert not Counter(kept) - Counter(stream_messages(data)), "a kept message is not in the original"


def test_no_backup_keeps_what_a_backup_run_keeps(original: Path, tmp_path: Path) -> None:
    kept = {}
    for backup in (True, False):
        bag = rewrite(original, tmp_path / f"copy-{backup}", Shape(chunked=False, crcs=False))
        path = _file(bag)
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
        repair_bag(bag, backup=backup)
        kept[backup] = _kept(bag)
        assert (bag / f"{path.name}.damaged").exists() == backup
        assert not list(bag.glob("*.repairing*"))
    assert kept[True] == kept[False] and len(kept[True]) > 250


def test_a_cut_file_compressed_bag_keeps_its_readable_prefix(original: Path, tmp_path: Path) -> None:
    bag = rewrite(original, tmp_path / "copy", Shape(chunked=False, file_compression=True))
    path = _file(bag)
    full = mcap_bytes(path)
    packed = io.BytesIO()  # zstd decodes whole blocks only: blocks of 8 KiB, so a cut loses at most one
    writer = zstandard.ZstdCompressor().stream_writer(packed, closefd=False)
    for start in range(0, len(full), 8192):
        writer.write(full[start : start + 8192])
        writer.flush(zstandard.FLUSH_BLOCK)
    writer.close()
    path.write_bytes(packed.getvalue()[: len(packed.getvalue()) * 2 // 3])
    out = io.StringIO()
    assert repair(bag, stdout=out, stderr=io.StringIO()) == 0, out.getvalue()
    assert path.name.endswith(".mcap.zstd") and (bag / f"{path.name}.damaged").exists()
    kept = _kept(bag)
    assert 0 < len(kept) < 600
    assert not Counter(kept) - Counter(stream_messages(full))


def test_a_flipped_payload_bit_without_crcs_is_not_seen(original: Path, tmp_path: Path) -> None:
    """Documented limit (docs/BAGS.md): without CRCs only framing and truncation can be found."""
    bag = rewrite(original, tmp_path / "copy", Shape(chunked=False, crcs=False))
    path = _file(bag)
    data = bytearray(path.read_bytes())
    _, end, _ = next(r for r in _records(bytes(data)) if r[2] == 0x05)
    data[end - 1] ^= 0x01  # the last byte of a message's payload
    path.write_bytes(bytes(data))
    assert {item.status for item in repair_bag(bag).files} == {"intact"}
    assert path.read_bytes() == bytes(data)
