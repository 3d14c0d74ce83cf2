"""MCAP record layouts for ``smm-bag repair`` (mcap.dev/spec): framing, chunks, footer and summary.

Records are ``<opcode u8><length u64><body>``. The bodies are read with the ``mcap`` library's record
classes through a stream that fails on a short read, so a field running past its record is an error.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from io import BytesIO

import lz4.frame  # type: ignore[import-untyped]
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, ChunkIndex, Footer, Message, MetadataIndex, Schema, Statistics

from smm_bag.storage import MCAP_MAGIC

__all__ = [
    "CHUNK_FIXED",
    "MESSAGE_FIXED",
    "PARSE_ERRORS",
    "PREFIX",
    "TAIL",
    "Summary",
    "chunk_fields",
    "chunk_records",
    "decompress",
    "read_footer",
    "read_summary",
    "stream",
]

PREFIX = struct.Struct("<BQ")
CHUNK_FIXED = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, compression length
MESSAGE_FIXED = struct.Struct("<HIQQ")  # channel, sequence, log time, publish time
_FOOTER_RECORD = 9 + 20
TAIL = _FOOTER_RECORD + len(MCAP_MAGIC)
_COMPRESSIONS = ("", "zstd", "lz4")
PARSE_ERRORS = (
    McapError,
    ValueError,
    EOFError,
    struct.error,
    KeyError,
    IndexError,
    OverflowError,
    zstandard.ZstdError,
)


class _Exact(ReadDataStream):
    """A ReadDataStream that fails on a short read (a field running past the record)."""

    def read(self, length: int) -> bytes:
        data = super().read(length)
        if len(data) != length:
            raise EOFError("field runs past the end of the record")
        return data


def stream(body: bytes) -> _Exact:
    """A record body as a stream for the ``mcap`` record classes' ``read``."""
    return _Exact(BytesIO(body))


@dataclass
class Summary:
    """The summary section's records; ``checked`` if its CRC was written and checks."""

    checked: bool
    start: int
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    chunk_indexes: list[ChunkIndex] = field(default_factory=list)
    metadata_indexes: list[MetadataIndex] = field(default_factory=list)
    statistics: Statistics | None = None
    other: int = 0


def decompress(compression: str, data: bytes, size: int) -> bytes:
    """A chunk's records uncompressed (``size``: the uncompressed size the chunk states, bytes)."""
    if compression == "zstd":
        return bytes(zstandard.ZstdDecompressor().decompress(data, max_output_size=size))
    if compression == "lz4":
        return bytes(lz4.frame.decompress(data))
    return data


def chunk_records(records: bytes) -> Iterator[tuple[int, Schema | Channel | Message]]:
    """``(offset in the records, record)`` of the Schema, Channel and Message records of a chunk's records.

    Raises:
        ValueError: A record runs past the end or does not parse.
    """
    position, end = 0, len(records)
    while position < end:
        if end - position < 9:
            raise ValueError(f"record header at {position} runs past the chunk's end")
        opcode, length = PREFIX.unpack_from(records, position)
        body = position + 9
        if length > end - body:
            raise ValueError(f"record at {position} runs past the chunk's end")
        item: Schema | Channel | Message | None = None
        if opcode == Opcode.MESSAGE:
            channel, sequence, log_time, publish_time = MESSAGE_FIXED.unpack_from(records, body)
            item = Message(
                channel, log_time, bytes(records[body + 22 : body + length]), publish_time, sequence
            )
        elif opcode == Opcode.SCHEMA:
            item = Schema.read(stream(records[body : body + length]))
        elif opcode == Opcode.CHANNEL:
            item = Channel.read(stream(records[body : body + length]))
        elif opcode == 0:
            raise ValueError(f"opcode 0 at {position}")
        if item is not None:
            yield position, item
        position = body + length


def chunk_fields(data: bytes, offset: int, limit: int) -> tuple[int, int, int, str, int, int] | None:
    """``(length, uncompressed size, crc, compression, records start, records length)`` if framed well."""
    if offset + 9 + CHUNK_FIXED.size > limit or data[offset] != Opcode.CHUNK:
        return None
    (length,) = struct.unpack_from("<Q", data, offset + 1)
    body = offset + 9
    if length < CHUNK_FIXED.size + 8 or length > limit - body:
        return None
    _, _, size, crc, name_length = CHUNK_FIXED.unpack_from(data, body)
    if name_length > 4 or CHUNK_FIXED.size + name_length + 8 > length:
        return None
    try:
        compression = bytes(data[body + CHUNK_FIXED.size : body + CHUNK_FIXED.size + name_length]).decode(
            "ascii"
        )
    except UnicodeDecodeError:
        return None
    (records_length,) = struct.unpack_from("<Q", data, body + CHUNK_FIXED.size + name_length)
    records_start = body + CHUNK_FIXED.size + name_length + 8
    if compression not in _COMPRESSIONS or records_start + records_length > body + length:  # may be padded
        return None
    return 9 + length, size, crc, compression, records_start, records_length


def read_footer(data: bytes) -> Footer | None:
    """The Footer before the trailing magic, if the file ends in one whose offsets fit the file."""
    size = len(data)
    if size < len(MCAP_MAGIC) + TAIL or bytes(data[size - len(MCAP_MAGIC) :]) != MCAP_MAGIC:
        return None
    at = size - TAIL
    if PREFIX.unpack_from(data, at) != (Opcode.FOOTER, 20):
        return None
    footer: Footer = Footer.read(stream(bytes(data[at + 9 : at + 29])))
    if footer.summary_start and not len(MCAP_MAGIC) < footer.summary_start <= at:
        return None
    if footer.summary_offset_start and not footer.summary_start < footer.summary_offset_start <= at:
        return None
    return footer


def read_summary(data: bytes, footer: Footer) -> Summary | None:
    """The summary section's records and whether its CRC was written and checks.

    Raises:
        ValueError: (or another of ``PARSE_ERRORS``) the summary does not parse.
    """
    if footer.summary_start == 0:
        return None
    footer_at = len(data) - TAIL
    crc = zlib.crc32(data[footer.summary_start : footer_at + 25])
    summary = Summary(
        checked=footer.summary_crc != 0 and crc == footer.summary_crc, start=footer.summary_start
    )
    position = footer.summary_start
    end = footer.summary_offset_start or footer_at
    while position < end:
        opcode, length = PREFIX.unpack_from(data, position)
        if length > end - position - 9:
            raise ValueError("summary record runs past the summary")
        body = stream(bytes(data[position + 9 : position + 9 + length]))
        if opcode == Opcode.SCHEMA:
            schema = Schema.read(body)
            summary.schemas[schema.id] = schema
        elif opcode == Opcode.CHANNEL:
            channel = Channel.read(body)
            summary.channels[channel.id] = channel
        elif opcode == Opcode.CHUNK_INDEX:
            summary.chunk_indexes.append(ChunkIndex.read(body))
        elif opcode == Opcode.METADATA_INDEX:
            summary.metadata_indexes.append(MetadataIndex.read(body))
        elif opcode == Opcode.STATISTICS:
            summary.statistics = Statistics.read(body)
        else:
            summary.other += 1
        position += 9 + length
    return summary
