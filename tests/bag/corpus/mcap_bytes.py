"""MCAP records written and read byte by byte after the specification, independent of the stack and of mcap.

The encoder builds the conformance shapes (padding, CRC 0, repeated schemas/channels, ...); the sequential
reader is the oracle of the damaged copies: records in order from the magic, a record whose framing checks
but whose present CRC (or, for a chunk, its contents) fails is skipped whole, and after a record whose
framing fails reading resumes at the next offset where a data-section record checks and the record after
it is framed too (or it ends the file), and only at a Chunk whose CRC is written and checks in a file whose
chunks carry CRCs: the rule of docs/BAGS.md, "Reading on after damage".
"""

from __future__ import annotations

import re
import struct
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import lz4.frame
import zstandard

MAGIC = b"\x89MCAP0\r\n"

HEADER, FOOTER, SCHEMA, CHANNEL, MESSAGE, CHUNK, MESSAGE_INDEX, CHUNK_INDEX = 1, 2, 3, 4, 5, 6, 7, 8
ATTACHMENT, ATTACHMENT_INDEX, STATISTICS, METADATA, METADATA_INDEX, SUMMARY_OFFSET, DATA_END = range(9, 16)
OPCODES = range(1, 16)
_DATA_SECTION = {SCHEMA, CHANNEL, MESSAGE, CHUNK, MESSAGE_INDEX, ATTACHMENT, METADATA, DATA_END}
"""What a resynchronisation may land on (docs/BAGS.md, "Reading on after damage")."""


# ------------------------------------------------------------------------------------------------ encoding


def string(text: str) -> bytes:
    raw = text.encode()
    return struct.pack("<I", len(raw)) + raw


def string_map(entries: Mapping[str, str]) -> bytes:
    body = b"".join(string(k) + string(v) for k, v in sorted(entries.items()))
    return struct.pack("<I", len(body)) + body


def record(opcode: int, content: bytes, pad: int = 0) -> bytes:
    """One record; ``pad`` extra bytes at its end, which readers must skip."""
    content += b"\xa5" * pad
    return struct.pack("<BQ", opcode, len(content)) + content


def header(profile: str, library: str) -> bytes:
    return string(profile) + string(library)


def schema(schema_id: int, name: str, encoding: str, data: bytes) -> bytes:
    return (
        struct.pack("<H", schema_id) + string(name) + string(encoding) + struct.pack("<I", len(data)) + data
    )


def channel(channel_id: int, schema_id: int, topic: str, encoding: str, metadata: Mapping[str, str]) -> bytes:
    return struct.pack("<HH", channel_id, schema_id) + string(topic) + string(encoding) + string_map(metadata)


def message(channel_id: int, sequence: int, log_time: int, publish_time: int, data: bytes) -> bytes:
    return struct.pack("<HIQQ", channel_id, sequence, log_time, publish_time) + data


def metadata(name: str, entries: Mapping[str, str]) -> bytes:
    return string(name) + string_map(entries)


# ------------------------------------------------------------------------------------------ sequential read


@dataclass(frozen=True)
class Message:
    """A message as the comparisons see it: topic, log time, publish time, bytes."""

    topic: str
    log_time: int
    publish_time: int
    data: bytes


@dataclass
class SequentialRead:
    """What a sequential read of one file gives."""

    messages: list[Message] = field(default_factory=list)
    skipped: list[tuple[int, str]] = field(default_factory=list)
    """(offset, reason) of each record skipped or place resynchronised from."""


class _BadRecordError(Exception):
    pass


class _Cursor:
    def __init__(self, data: bytes | memoryview, start: int, end: int) -> None:
        self.data, self.pos, self.end = data, start, end

    def take(self, size: int) -> bytes:
        if self.pos + size > self.end:
            raise _BadRecordError("field past the record's end")
        value = bytes(self.data[self.pos : self.pos + size])
        self.pos += size
        return value

    def unpack(self, fmt: str) -> tuple[int, ...]:
        return struct.unpack(fmt, self.take(struct.calcsize(fmt)))

    def string(self) -> str:
        (size,) = self.unpack("<I")
        try:
            return self.take(size).decode()
        except UnicodeDecodeError as error:
            raise _BadRecordError("string not UTF-8") from error

    def blob(self, fmt: str) -> bytes:
        (size,) = self.unpack(fmt)
        return self.take(size)

    def string_map(self) -> dict[str, str]:
        body = self.blob("<I")
        inner = _Cursor(body, 0, len(body))
        entries = {}
        while inner.pos < inner.end:
            key = inner.string()
            entries[key] = inner.string()
        return entries


def _decompress(compression: str, payload: bytes, size: int) -> bytes:
    try:
        if compression == "":
            return payload
        if compression == "zstd":
            return zstandard.ZstdDecompressor().decompress(payload, max_output_size=size)
        if compression == "lz4":
            return bytes(lz4.frame.decompress(payload))
    except Exception as error:  # any decoder failure is a failed record
        raise _BadRecordError(f"{compression} does not decompress") from error
    raise _BadRecordError(f"unknown compression {compression!r}")


class _Reader:
    def __init__(self, data: bytes) -> None:
        self.data = data
        self.schemas: set[int] = set()
        self.topics: dict[int, str] = {}
        self.out = SequentialRead()
        self.chunk_crcs: bool | None = None
        """Whether the file's chunks carry CRCs, from the first chunk that checked (None: none yet)."""

    def parse(self, pos: int, end_limit: int, inside_chunk: bool = False) -> tuple[int, list[Message]]:
        """Checks the record at ``pos``; returns its end and its messages (raises if it fails)."""
        data = self.data
        if pos + 9 > end_limit:
            raise _BadRecordError("record header past the end")
        opcode, length = struct.unpack_from("<BQ", data, pos)
        allowed = (SCHEMA, CHANNEL, MESSAGE) if inside_chunk else OPCODES
        if opcode not in allowed:
            raise _BadRecordError(f"opcode {opcode:#x}")
        end = pos + 9 + length
        if end > end_limit:
            raise _BadRecordError("length past the end")
        cursor = _Cursor(data, pos + 9, end)
        found: list[Message] = []
        if opcode == HEADER:
            cursor.string(), cursor.string()
        elif opcode == FOOTER:
            cursor.unpack("<QQI")
        elif opcode == SCHEMA:
            (schema_id,) = cursor.unpack("<H")
            cursor.string(), cursor.string(), cursor.blob("<I")
            self.schemas.add(schema_id)
        elif opcode == CHANNEL:
            channel_id, _ = cursor.unpack("<HH")
            topic = cursor.string()
            cursor.string(), cursor.string_map()
            self.topics[channel_id] = topic
        elif opcode == MESSAGE:
            channel_id, _, log_time, publish_time = cursor.unpack("<HIQQ")
            if channel_id not in self.topics:
                raise _BadRecordError(f"message of unknown channel {channel_id}")
            found.append(Message(self.topics[channel_id], log_time, publish_time, data[cursor.pos : end]))
        elif opcode == CHUNK:
            _, _, size, crc = cursor.unpack("<QQQI")
            compression = cursor.string()
            payload = cursor.blob("<Q")
            # The chunk's own fields are framed: whatever fails inside it skips it whole.
            try:
                inner = _decompress(compression, payload, size)
                if len(inner) != size:
                    raise _BadRecordError("uncompressed size differs")
                if crc and zlib.crc32(inner) != crc:
                    raise _CrcFailedError("chunk CRC mismatch")
                sub = _Reader(inner)
                sub.schemas, sub.topics = self.schemas.copy(), self.topics.copy()
                at = 0
                while at < len(inner):
                    at, messages = sub.parse(at, len(inner), inside_chunk=True)
                    found.extend(messages)
            except (_BadRecordError, struct.error) as error:
                raise _CrcFailedError(f"chunk records: {error}") from error
            self.schemas, self.topics = sub.schemas, sub.topics
            if self.chunk_crcs is None and not inside_chunk:
                self.chunk_crcs = crc != 0
        elif opcode == MESSAGE_INDEX:
            cursor.unpack("<H")
            if len(cursor.blob("<I")) % 16:
                raise _BadRecordError("message index entries")
        elif opcode == CHUNK_INDEX:
            cursor.unpack("<QQQQ")
            if len(cursor.blob("<I")) % 10:
                raise _BadRecordError("chunk index offsets")
            cursor.unpack("<Q")
            cursor.string()
            cursor.unpack("<QQ")
        elif opcode == ATTACHMENT:
            start = cursor.pos
            cursor.unpack("<QQ")
            cursor.string(), cursor.string(), cursor.blob("<Q")
            covered = data[start : cursor.pos]
            (crc,) = cursor.unpack("<I")
            if crc and zlib.crc32(covered) != crc:
                raise _CrcFailedError("attachment CRC mismatch")
        elif opcode == ATTACHMENT_INDEX:
            cursor.unpack("<QQQQQ")
            cursor.string(), cursor.string()
        elif opcode == STATISTICS:
            cursor.unpack("<QHIIIIQQ")
            if len(cursor.blob("<I")) % 10:
                raise _BadRecordError("statistics counts")
        elif opcode == METADATA:
            cursor.string(), cursor.string_map()
        elif opcode == METADATA_INDEX:
            cursor.unpack("<QQ")
            cursor.string()
        elif opcode == SUMMARY_OFFSET:
            cursor.unpack("<BQQ")
        elif opcode == DATA_END:
            (crc,) = cursor.unpack("<I")
            if crc and zlib.crc32(data[:pos]) != crc:
                raise _CrcFailedError("data section CRC mismatch")
        return end, found

    def run(self) -> SequentialRead:
        data = self.data
        if data[:8] != MAGIC:
            self.out.skipped.append((0, "no magic"))
        pos = 8
        while pos < len(data):
            if data[pos:] == MAGIC:
                break
            try:
                end, messages = self.parse(pos, len(data))
            except _CrcFailedError as error:
                self.out.skipped.append((pos, str(error)))
                pos = pos + 9 + struct.unpack_from("<Q", data, pos + 1)[0]
                continue
            except (_BadRecordError, struct.error) as error:
                self.out.skipped.append((pos, f"framing: {error}"))
                pos = self._resync(pos + 1)
                continue
            self.out.messages.extend(messages)
            if data[pos] == FOOTER:
                break
            pos = end
        return self.out

    def _resync(self, start: int, crc_chunks_only: bool | None = None) -> int:
        """The next offset >= start where a record's framing and present CRC check (len(data) if none); in
        a file whose chunks carry CRCs (those read so far, else the next chunk that checks) only a Chunk
        whose CRC is written and checks."""
        if crc_chunks_only is None:
            crc_chunks_only = self.chunk_crcs
            if crc_chunks_only is None:
                after = self._resync(start, crc_chunks_only=False)
                while after < len(self.data) and self.data[after] != CHUNK:
                    after = self._resync(after + 1, crc_chunks_only=False)
                crc_chunks_only = after < len(self.data) and _chunk_crc(self.data, after) != 0
        for match in _CANDIDATE.finditer(self.data, start):
            at = match.start()
            if self.data[at] not in _DATA_SECTION:
                continue
            if crc_chunks_only and (self.data[at] != CHUNK or _chunk_crc(self.data, at) == 0):
                continue
            snapshot = (self.schemas.copy(), self.topics.copy(), self.chunk_crcs)
            try:
                end, _ = self.parse(at, len(self.data))
            except (_BadRecordError, _CrcFailedError, struct.error):
                continue
            finally:
                self.schemas, self.topics, self.chunk_crcs = snapshot
            if end == len(self.data) or _framed(self.data, end):
                return at
        return len(self.data)


class _CrcFailedError(Exception):
    """A record whose own framing checks but whose CRC or contents fail: skipped whole."""


def _chunk_crc(data: bytes, pos: int) -> int:
    """The uncompressed CRC field of the Chunk record at ``pos`` (0 if the file ends first)."""
    return struct.unpack_from("<I", data, pos + 33)[0] if pos + 37 <= len(data) else 0


def _framed(data: bytes, pos: int) -> bool:
    """Whether a data-section record (no Header; a Message at least its fixed fields) is framed at ``pos``."""
    if pos + 9 > len(data):
        return False
    opcode, length = struct.unpack_from("<BQ", data, pos)
    return (
        opcode in OPCODES
        and opcode != HEADER
        and length <= len(data) - pos - 9
        and (opcode != MESSAGE or length >= 22)
    )


# An opcode, then a length below 2^32: the only offsets worth parsing when resynchronising.
_CANDIDATE = re.compile(rb"(?=[\x01-\x0f][\x00-\xff]{4}\x00\x00\x00\x00)", re.DOTALL)


def sequential_read(data: bytes) -> SequentialRead:
    """Every message a sequential read of one MCAP file's bytes gives (the oracle of damaged copies)."""
    return _Reader(data).run()


def iter_records(data: bytes) -> Iterator[tuple[int, int, int]]:
    """(offset, opcode, end) of each top-level record of an undamaged file, from the magic to the footer."""
    pos = 8
    while pos + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        yield pos, opcode, pos + 9 + length
        if opcode == FOOTER:
            return
        pos += 9 + length
