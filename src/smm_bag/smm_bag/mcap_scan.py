"""MCAP record scanner of ``smm-bag repair``: which records of a file check, and where it is damaged.

Follows the MCAP specification (mcap.dev/spec): a Chunk's
``uncompressed_crc`` covers its uncompressed records, DataEnd's ``data_section_crc`` every byte before it,
the Footer's ``summary_crc`` the summary section up to and including the Footer's ``summary_offset_start``.
A CRC of 0 means "not written". Record layouts: :mod:`smm_bag.mcap_records`.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field

import zstandard
from mcap.opcode import Opcode
from mcap.records import Channel, DataEnd, Header, Message, MessageIndex, Metadata, Schema

from smm_bag.mcap_records import (
    PARSE_ERRORS,
    PREFIX,
    Summary,
    chunk_fields,
    chunk_records,
    decompress,
    read_footer,
    read_summary,
    stream,
)
from smm_bag.reader import MCAP_MAGIC

__all__ = ["Damage", "FileScan", "GoodChunk", "chunk_data", "scan_mcap"]

_DATA_OPCODES = frozenset(
    {
        Opcode.HEADER,
        Opcode.SCHEMA,
        Opcode.CHANNEL,
        Opcode.MESSAGE,
        Opcode.CHUNK,
        Opcode.MESSAGE_INDEX,
        Opcode.ATTACHMENT,
        Opcode.METADATA,
        Opcode.DATA_END,
    }
)
_OUTSIDE_CHUNKS = (
    " (a byte no chunk CRC covers changed: the Header, a metadata record, a message index or a chunk's"
    " fixed fields)"
)


@dataclass(frozen=True)
class Damage:
    """A damaged place: bytes ``[start, end)`` of the file and what is wrong there."""

    start: int
    end: int
    what: str


@dataclass(frozen=True)
class GoodChunk:
    """A Chunk record whose records check (CRC written and equal, or no CRC and found where expected).

    Attributes:
        offset: File offset of the record (its opcode byte).
        length: Record length including opcode and length prefix (bytes).
        compression: ``""``, ``"zstd"`` or ``"lz4"``.
        crc_checked: True if the chunk CRC was written and checks.
        counts: Messages per channel id.
        spans: Earliest and latest message log time per channel id (ns).
        start_ns: Earliest message log time (None: no message).
        end_ns: Latest message log time (None: no message).
    """

    offset: int
    length: int
    compression: str
    crc_checked: bool
    counts: dict[int, int]
    spans: dict[int, tuple[int, int]]
    start_ns: int | None
    end_ns: int | None


@dataclass
class FileScan:
    """What :func:`scan_mcap` found in one file."""

    size: int
    header: Header | None = None
    chunks: list[GoodChunk] = field(default_factory=list)
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: list[tuple[int, int, Metadata]] = field(default_factory=list)
    damage: list[Damage] = field(default_factory=list)
    summary: Summary | None = None
    data_end: int | None = None
    data_crc: str = "missing"
    inconsistencies: list[str] = field(default_factory=list)
    bad_chunks: int = 0
    top_level_messages: int = 0
    truncated: bool = False

    @property
    def intact(self) -> bool:
        """Every CRC written and checking, data section read end to end, summary equal to the data."""
        return (
            not self.damage
            and not self.inconsistencies
            and not self.truncated
            and self.header is not None
            and self.data_crc in ("checks", "not written")
            and self.summary is not None
            and self.summary.checked
            and all(chunk.crc_checked for chunk in self.chunks)
        )

    @property
    def findings(self) -> list[str]:
        """Every damaged place and disagreement, in file order, as text."""
        found = ["truncated (no MCAP footer)"] if self.truncated else []
        found += [f"bytes {d.start}-{d.end}: {d.what}" for d in self.damage]
        if self.data_crc == "mismatch":
            found.append("data section CRC mismatch" + ("" if self.damage else _OUTSIDE_CHUNKS))
        return found + self.inconsistencies


def chunk_data(data: bytes, chunk: GoodChunk) -> bytes:
    """The uncompressed records of a chunk found by :func:`scan_mcap`."""
    fields = chunk_fields(data, chunk.offset, len(data))
    assert fields is not None
    _, size, _, compression, start, length = fields
    return decompress(compression, bytes(data[start : start + length]), size)


def _check_chunk(data: bytes, offset: int, limit: int, trusted: bool) -> tuple[GoodChunk, bytes] | str:
    """The chunk at ``offset`` and its records if they check, else why not."""
    fields = chunk_fields(data, offset, limit)
    if fields is None:
        return "chunk framing damaged"
    length, size, crc, compression, start, records_length = fields
    try:
        records = decompress(compression, bytes(data[start : start + records_length]), size)
    except (zstandard.ZstdError, RuntimeError, ValueError, MemoryError, OverflowError) as error:
        return f"chunk does not decompress ({error})"
    if crc != 0 and zlib.crc32(records) != crc:
        return "chunk CRC mismatch"
    if crc == 0 and not trusted:
        return "chunk without CRC found outside the index"
    counts: dict[int, int] = {}
    spans: dict[int, tuple[int, int]] = {}
    try:
        for _, record in chunk_records(records):
            if isinstance(record, Message):
                channel, time = record.channel_id, record.log_time
                counts[channel] = counts.get(channel, 0) + 1
                low, high = spans.get(channel, (time, time))
                spans[channel] = (min(low, time), max(high, time))
    except PARSE_ERRORS as error:
        return f"chunk records malformed ({error})"
    start_ns = min((low for low, _ in spans.values()), default=None)
    end_ns = max((high for _, high in spans.values()), default=None)
    return GoodChunk(offset, length, compression, crc != 0, counts, spans, start_ns, end_ns), records


def _record(data: bytes, offset: int, limit: int) -> tuple[int, int] | None:
    """``(opcode, end offset)`` of a plausibly framed data-section record at ``offset``, else None."""
    if offset + 9 > limit:
        return None
    opcode, length = PREFIX.unpack_from(data, offset)
    if opcode not in _DATA_OPCODES or length > limit - offset - 9:
        return None
    return opcode, offset + 9 + length


def _resync(data: bytes, start: int, limit: int, index: list[int]) -> int:
    """Offset of the next chunk at or after ``start`` whose CRC checks (``limit`` if none).

    With a summary that checks, its chunk index lists every chunk: the next indexed offset is used.
    Otherwise the bytes are searched for a Chunk record whose framing fits and whose CRC checks.
    """
    if index:
        return next((offset for offset in index if offset >= start), limit)
    position = start
    while True:
        position = data.find(bytes([Opcode.CHUNK]), position, limit)
        if position < 0:
            return limit
        if chunk_fields(data, position, limit) is not None and not isinstance(
            _check_chunk(data, position, limit, trusted=False), str
        ):
            return position
        position += 1


def scan_mcap(data: bytes) -> FileScan:
    """Reads every record of an MCAP file's bytes, keeping those that check, and notes the damage."""
    scan = FileScan(size=len(data))
    footer = read_footer(data)
    try:
        summary = read_summary(data, footer) if footer is not None else None
    except PARSE_ERRORS as error:
        summary = None
        scan.inconsistencies.append(f"summary unreadable although its CRC checks ({error})")
    if footer is None:
        scan.truncated = bytes(data[-len(MCAP_MAGIC) :]) != MCAP_MAGIC
        if not scan.truncated:
            scan.inconsistencies.append("footer damaged")
    elif summary is not None and not summary.checked:
        scan.inconsistencies.append(
            "summary CRC mismatch" if footer.summary_crc else "summary without CRC (not verifiable)"
        )
    scan.summary = summary if summary is not None and summary.checked else None
    limit = scan.summary.start if scan.summary is not None else len(data)
    index = sorted(entry.chunk_start_offset for entry in scan.summary.chunk_indexes) if scan.summary else []
    indexed = set(index)
    message_indexes: dict[int, MessageIndex] = {}
    expected_indexes: dict[int, dict[int, list[tuple[int, int]]]] = {}
    top_level: list[tuple[int, Schema | Channel]] = []
    clean = bytes(data[: len(MCAP_MAGIC)]) == MCAP_MAGIC
    position = len(MCAP_MAGIC)
    if not clean:
        scan.damage.append(Damage(0, len(MCAP_MAGIC), "MCAP magic damaged"))
    while position < limit:
        framed = _record(data, position, limit)
        if framed is None or (framed[0] == Opcode.HEADER) != (position == len(MCAP_MAGIC)):
            after = _resync(data, position + 1, limit, index)
            scan.damage.append(Damage(position, after, "unreadable bytes (record framing damaged)"))
            clean, position = False, after
            continue
        opcode, end = framed
        body = bytes(data[position + 9 : end]) if opcode != Opcode.CHUNK else b""
        try:
            if opcode == Opcode.CHUNK:
                found = _check_chunk(data, position, limit, trusted=clean or position in indexed)
                if isinstance(found, str):
                    # Its length may be what is damaged: go on at the next chunk that checks, not at its end.
                    scan.bad_chunks += 1
                    scan.damage.append(Damage(position, end, found))
                    clean = False
                    end = _resync(data, position + 1, limit, index)
                else:
                    chunk, records = found
                    scan.chunks.append(chunk)
                    expected = expected_indexes.setdefault(position, {})
                    for offset, record in chunk_records(records):
                        if isinstance(record, Message):
                            expected.setdefault(record.channel_id, []).append((record.log_time, offset))
                        elif isinstance(record, Schema):
                            scan.schemas.setdefault(record.id, record)
                        else:
                            scan.channels.setdefault(record.id, record)
            elif opcode == Opcode.HEADER:
                scan.header = Header.read(stream(body))
            elif opcode == Opcode.DATA_END:
                written = DataEnd.read(stream(body)).data_section_crc
                scan.data_end = position
                if written == 0:
                    scan.data_crc = "not written"
                else:
                    with memoryview(data) as view:  # no copy of the data section
                        crc = zlib.crc32(view[:position])
                    scan.data_crc = "checks" if crc == written else "mismatch"
                position = end
                break
            elif opcode == Opcode.METADATA:
                scan.metadata.append((position, end - position, Metadata.read(stream(body))))
            elif opcode == Opcode.MESSAGE_INDEX:
                message_indexes[position] = MessageIndex.read(stream(body))
            elif opcode == Opcode.SCHEMA and clean:
                top_level.append((position, Schema.read(stream(body))))
            elif opcode == Opcode.CHANNEL and clean:
                top_level.append((position, Channel.read(stream(body))))
            elif opcode == Opcode.MESSAGE:
                scan.top_level_messages += 1
        except PARSE_ERRORS as error:
            scan.damage.append(Damage(position, end, f"record {Opcode(opcode).name} malformed ({error})"))
            clean = False
        position = end
    if scan.data_end is None:
        scan.inconsistencies.append("no Data End record (data section does not end)")
    elif scan.summary is not None and position != scan.summary.start:
        scan.inconsistencies.append("bytes between the Data End record and the summary")
    trusted = scan.data_crc == "checks" or (scan.data_crc == "not written" and clean)
    for _, record in top_level if trusted else []:
        if isinstance(record, Schema):
            scan.schemas.setdefault(record.id, record)
        else:
            scan.channels.setdefault(record.id, record)
    if scan.summary is not None:
        _compare_summary(scan, scan.summary, message_indexes, expected_indexes)
    return scan


def _compare_summary(
    scan: FileScan,
    summary: Summary,
    message_indexes: dict[int, MessageIndex],
    expected: dict[int, dict[int, list[tuple[int, int]]]],
) -> None:
    """Notes every way the summary (whose CRC checks) disagrees with the data section."""
    for kind, copies, found in (
        ("schema", summary.schemas, scan.schemas),
        ("channel", summary.channels, scan.channels),
    ):
        for key, record in copies.items():
            if key in found and found[key] != record:
                scan.inconsistencies.append(f"summary {kind} {key} differs from the data section's")
            found.setdefault(key, record)  # type: ignore[arg-type]
    chunks = {chunk.offset: chunk for chunk in scan.chunks}
    for entry in summary.chunk_indexes:
        chunk = chunks.get(entry.chunk_start_offset)
        if chunk is None:
            scan.inconsistencies.append(f"indexed chunk at byte {entry.chunk_start_offset} not found")
            continue
        if (entry.chunk_length, entry.compression) != (chunk.length, chunk.compression) or (
            chunk.counts
            and (entry.message_start_time, entry.message_end_time) != (chunk.start_ns, chunk.end_ns)
        ):
            scan.inconsistencies.append(
                f"chunk index of byte {entry.chunk_start_offset} disagrees with the chunk"
            )
        wanted = expected.get(entry.chunk_start_offset, {})
        got = {
            channel: message_indexes.get(offset) for channel, offset in entry.message_index_offsets.items()
        }
        if got and {c: (i.records if i else None) for c, i in got.items()} != wanted:
            scan.inconsistencies.append(
                f"message index of the chunk at byte {entry.chunk_start_offset} wrong"
            )
    if len(summary.chunk_indexes) != len(scan.chunks):
        scan.inconsistencies.append(
            f"summary indexes {len(summary.chunk_indexes)} chunks, the data section holds {len(scan.chunks)}"
        )
    stats = summary.statistics
    counts: dict[int, int] = {}
    for chunk in scan.chunks:
        for channel, count in chunk.counts.items():
            counts[channel] = counts.get(channel, 0) + count
    if stats is None:
        scan.inconsistencies.append("summary has no Statistics record")
    elif (
        stats.message_count != sum(counts.values()) + scan.top_level_messages
        or {k: v for k, v in stats.channel_message_counts.items() if v} != counts
        or stats.chunk_count != len(scan.chunks)
    ):
        scan.inconsistencies.append("summary statistics disagree with the data section")
    records = {(offset, length): record.name for offset, length, record in scan.metadata}
    for index in summary.metadata_indexes:
        if records.get((index.offset, index.length)) != index.name:
            scan.inconsistencies.append(f"metadata index of byte {index.offset} points at no such record")
