"""MCAP record scanner: which records of a file check, where it is damaged, where its messages are.

Follows the MCAP specification (mcap.dev/spec): a Chunk's
``uncompressed_crc`` covers its uncompressed records, DataEnd's ``data_section_crc`` every byte before it,
the Footer's ``summary_crc`` the summary section up to and including the Footer's ``summary_offset_start``.
A CRC of 0 means "not written"; a missing summary, index or statistics record is not damage.
Record layouts: :mod:`smm_bag.mcap_records`.
"""

from __future__ import annotations

import re
import zlib
from dataclasses import dataclass, field

import zstandard
from mcap.opcode import Opcode
from mcap.records import Channel, DataEnd, Header, Message, MessageIndex, Metadata, Schema

from smm_bag.mcap_records import (
    MESSAGE_FIXED,
    PARSE_ERRORS,
    PREFIX,
    TAIL,
    Summary,
    chunk_fields,
    chunk_records,
    decompress,
    read_footer,
    read_summary,
    stream,
)
from smm_bag.storage import MCAP_MAGIC

__all__ = ["Block", "Damage", "FileScan", "GoodChunk", "MessageRun", "chunk_data", "scan_mcap"]

_MESSAGE = MESSAGE_FIXED
_MESSAGE_FIXED = MESSAGE_FIXED.size
_CANDIDATE = re.compile(rb"[\x03-\x07\x09\x0c\x0f].{5}\x00\x00\x00", re.DOTALL)
"""Where a data-section record may start: its opcode, then a length below 2**40 (a fast first filter)."""
_RUN_LENGTH = 4096
"""Most messages in one :class:`MessageRun` (an ordered read sorts one run at a time)."""

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
    """A Chunk record whose framing checks, whose CRC checks where written and whose records parse.

    Attributes:
        offset: File offset of the record (its opcode byte).
        length: Record length including opcode and length prefix (bytes).
        compression: ``""``, ``"zstd"`` or ``"lz4"``.
        crc_checked: True if the chunk CRC was written (and checks).
        counts: Messages per channel id.
        spans: Earliest and latest message log time per channel id (ns).
        start_ns: Earliest message log time (None: no message).
        end_ns: Latest message log time (None: no message).
        ordered: Its messages are in log-time order.
    """

    offset: int
    length: int
    compression: str
    crc_checked: bool
    counts: dict[int, int]
    spans: dict[int, tuple[int, int]]
    start_ns: int | None
    end_ns: int | None
    ordered: bool = True


@dataclass(frozen=True)
class MessageRun:
    """Consecutive Message records outside chunks: bytes ``[offset, end)``, counted like a chunk's."""

    offset: int
    end: int
    counts: dict[int, int]
    spans: dict[int, tuple[int, int]]
    start_ns: int
    end_ns: int
    ordered: bool


Block = GoodChunk | MessageRun
"""Where messages are: a chunk, or a run of messages outside chunks."""


@dataclass
class FileScan:
    """What :func:`scan_mcap` found in one file."""

    size: int
    header: Header | None = None
    chunks: list[GoodChunk] = field(default_factory=list)
    runs: list[MessageRun] = field(default_factory=list)
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    metadata: list[tuple[int, int, Metadata]] = field(default_factory=list)
    damage: list[Damage] = field(default_factory=list)
    summary: Summary | None = None
    data_end: int | None = None
    data_crc: str = "missing"
    inconsistencies: list[str] = field(default_factory=list)
    bad_chunks: int = 0
    truncated: bool = False

    @property
    def blocks(self) -> list[Block]:
        """Chunks and message runs in file order."""
        return sorted([*self.chunks, *self.runs], key=lambda block: block.offset)

    @property
    def top_level_messages(self) -> int:
        """Messages outside chunks."""
        return sum(sum(run.counts.values()) for run in self.runs)

    @property
    def intact(self) -> bool:
        """No framing check, written CRC or summary consistency check fails (absent parts are fine)."""
        return (
            not self.damage
            and not self.inconsistencies
            and not self.truncated
            and self.header is not None
            and self.data_crc != "mismatch"
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


def _counted(messages: list[tuple[int, int]]) -> tuple[dict[int, int], dict[int, tuple[int, int]], bool]:
    """Counts and log-time spans per channel of ``(channel, log time)`` pairs; whether they are ordered."""
    counts: dict[int, int] = {}
    spans: dict[int, tuple[int, int]] = {}
    ordered, last = True, -1
    for channel, time in messages:
        counts[channel] = counts.get(channel, 0) + 1
        low, high = spans.get(channel, (time, time))
        spans[channel] = (min(low, time), max(high, time))
        ordered, last = ordered and time >= last, time
    return counts, spans, ordered


def _check_chunk(data: bytes, offset: int, limit: int) -> tuple[GoodChunk, bytes] | str:
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
    try:
        messages = [
            (record.channel_id, record.log_time)
            for _, record in chunk_records(records)
            if isinstance(record, Message)
        ]
    except PARSE_ERRORS as error:
        return f"chunk records malformed ({error})"
    counts, spans, ordered = _counted(messages)
    start_ns = min((low for low, _ in spans.values()), default=None)
    end_ns = max((high for _, high in spans.values()), default=None)
    return GoodChunk(offset, length, compression, crc != 0, counts, spans, start_ns, end_ns, ordered), records


def _record(data: bytes, offset: int, limit: int) -> tuple[int, int] | None:
    """``(opcode, end offset)`` of a plausibly framed data-section record at ``offset``, else None."""
    if offset + 9 > limit:
        return None
    opcode, length = PREFIX.unpack_from(data, offset)
    if opcode not in _DATA_OPCODES or length > limit - offset - 9:
        return None
    if opcode == Opcode.MESSAGE and length < _MESSAGE_FIXED:
        return None
    if opcode == Opcode.DATA_END and length != 4 and offset + 9 + length != limit:
        return None  # a Data End holds a CRC and ends the data section: a Chunk opcode flipped to 0x0F
    return opcode, offset + 9 + length


def _resync(data: bytes, start: int, limit: int) -> int:
    """The first offset at or after ``start`` where a record checks (``limit`` if none): docs/BAGS.md.

    A record checks if it is framed as a data-section record (not a Header), a Chunk's fields parse, its
    CRC checks where written and its records parse, and the record after it is framed too (or it ends
    at ``limit``).
    """
    for match in _CANDIDATE.finditer(data, start, limit):
        position = match.start()
        framed = _record(data, position, limit)
        if framed is None or framed[0] == Opcode.HEADER:
            continue
        opcode, end = framed
        if end != limit and _record(data, end, limit) is None:
            continue
        if opcode == Opcode.CHUNK and isinstance(_check_chunk(data, position, limit), str):
            continue
        return position
    return limit


def _continues(data: bytes, end: int, limit: int) -> bool:
    """Whether a record follows ``end``: the data end, a framed record, or one cut by the file end."""
    if end == limit or _record(data, end, limit) is not None:
        return True
    if limit != len(data) or data[end] not in _DATA_OPCODES:
        return False
    return end + 9 > limit or PREFIX.unpack_from(data, end)[1] > limit - end - 9


def _chunks_carry_crcs(scan: FileScan, data: bytes, start: int, limit: int) -> bool:
    """Whether the file's chunks carry CRCs: those read so far, else the next chunk that checks."""
    if scan.chunks:
        return any(chunk.crc_checked for chunk in scan.chunks)
    for match in _CANDIDATE.finditer(data, start, limit):
        if data[match.start()] == Opcode.CHUNK:
            found = _check_chunk(data, match.start(), limit)
            if not isinstance(found, str):
                return found[0].crc_checked
    return False


def _read_summary(scan: FileScan, data: bytes) -> int:
    """Reads the footer and summary into ``scan``; returns where the data section must end."""
    footer = read_footer(data)
    if footer is None:
        scan.truncated = bytes(data[-len(MCAP_MAGIC) :]) != MCAP_MAGIC
        if not scan.truncated:
            scan.inconsistencies.append("footer damaged")
        return len(data)
    try:
        summary = read_summary(data, footer)
    except PARSE_ERRORS as error:
        scan.inconsistencies.append(f"summary unreadable ({error})")
        return footer.summary_start or len(data) - TAIL
    if summary is not None and footer.summary_crc != 0 and not summary.checked:
        scan.inconsistencies.append("summary CRC mismatch")
        return summary.start
    scan.summary = summary
    return summary.start if summary is not None else len(data) - TAIL


def scan_mcap(data: bytes) -> FileScan:
    """Reads every record of an MCAP file's bytes in order, keeping those that check, and notes the damage.

    After a record that does not check, reading goes on at the next offset where one does (:func:`_resync`).
    """
    scan = FileScan(size=len(data))
    limit = _read_summary(scan, data)
    message_indexes: dict[int, MessageIndex] = {}
    expected_indexes: dict[int, dict[int, list[tuple[int, int]]]] = {}
    run: list[tuple[int, int]] = []
    run_start = run_end = 0
    unverified = False  # reading on after damage, in a file whose chunks carry CRCs
    position = len(MCAP_MAGIC)
    if bytes(data[: len(MCAP_MAGIC)]) != MCAP_MAGIC:
        scan.damage.append(Damage(0, len(MCAP_MAGIC), "MCAP magic damaged"))

    def close_run() -> None:
        if run:
            counts, spans, ordered = _counted(run)
            low = min(time for _, time in run)
            high = max(time for _, time in run)
            scan.runs.append(MessageRun(run_start, run_end, counts, spans, low, high, ordered))
            run.clear()

    while position < limit:
        framed = _record(data, position, limit)
        if framed is None or (framed[0] == Opcode.HEADER) != (position == len(MCAP_MAGIC)):
            close_run()
            after = _resync(data, position + 1, limit)
            unverified = _chunks_carry_crcs(scan, data, after, limit)
            scan.damage.append(Damage(position, after, "unreadable bytes (record framing damaged)"))
            position = after
            continue
        opcode, end = framed
        if unverified and opcode != Opcode.CHUNK and not _continues(data, end, limit):
            # Read where no CRC vouches in a file that has CRCs: no record follows it, so it was cut short.
            close_run()
            after = _resync(data, position + 1, limit)
            scan.damage.append(Damage(position, after, "record not followed by a record (damaged)"))
            position = after
            continue
        if opcode != Opcode.MESSAGE or len(run) >= _RUN_LENGTH:
            close_run()
        body = bytes(data[position + 9 : end]) if opcode != Opcode.CHUNK else b""
        try:
            if opcode == Opcode.MESSAGE:
                if not run:
                    run_start = position
                channel, _, log_time, _ = _MESSAGE.unpack_from(body)
                run.append((channel, log_time))
                run_end = end
            elif opcode == Opcode.CHUNK:
                found = _check_chunk(data, position, limit)
                if isinstance(found, str):
                    # Framed well, its CRC or records fail: skip it. Its framing fails: go on where a record
                    # checks (its length may be what is damaged).
                    scan.bad_chunks += 1
                    if chunk_fields(data, position, limit) is None:
                        end = _resync(data, position + 1, limit)
                        unverified = _chunks_carry_crcs(scan, data, end, limit)
                    scan.damage.append(Damage(position, end, found))
                else:
                    chunk, records = found
                    scan.chunks.append(chunk)
                    unverified = unverified and not chunk.crc_checked
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
            elif opcode == Opcode.SCHEMA:
                schema = Schema.read(stream(body))
                scan.schemas.setdefault(schema.id, schema)
            elif opcode == Opcode.CHANNEL:
                channel_record = Channel.read(stream(body))
                scan.channels.setdefault(channel_record.id, channel_record)
        except PARSE_ERRORS as error:
            scan.damage.append(Damage(position, end, f"record {Opcode(opcode).name} malformed ({error})"))
        position = end
    close_run()
    if scan.data_end is None:
        if not scan.truncated:
            scan.inconsistencies.append("no Data End record (data section does not end)")
    elif scan.summary is not None and position != scan.summary.start:
        scan.inconsistencies.append("bytes between the Data End record and the summary")
    if scan.summary is not None:
        _compare_summary(scan, scan.summary, message_indexes, expected_indexes)
    return scan


def _compare_summary(
    scan: FileScan,
    summary: Summary,
    message_indexes: dict[int, MessageIndex],
    expected: dict[int, dict[int, list[tuple[int, int]]]],
) -> None:
    """Notes every way the summary disagrees with the data section (its absent parts are not checked)."""
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
    if summary.chunk_indexes and len(summary.chunk_indexes) != len(scan.chunks):
        scan.inconsistencies.append(
            f"summary indexes {len(summary.chunk_indexes)} chunks, the data section holds {len(scan.chunks)}"
        )
    stats = summary.statistics
    counts: dict[int, int] = {}
    for block in scan.blocks:
        for channel, count in block.counts.items():
            counts[channel] = counts.get(channel, 0) + count
    if stats is not None and (
        stats.message_count != sum(counts.values())
        or (
            stats.channel_message_counts
            and {k: v for k, v in stats.channel_message_counts.items() if v} != counts
        )
        or stats.chunk_count != len(scan.chunks)
    ):
        scan.inconsistencies.append("summary statistics disagree with the data section")
    records = {(offset, length): record.name for offset, length, record in scan.metadata}
    for index in summary.metadata_indexes:
        if records.get((index.offset, index.length)) != index.name:
            scan.inconsistencies.append(f"metadata index of byte {index.offset} points at no such record")
