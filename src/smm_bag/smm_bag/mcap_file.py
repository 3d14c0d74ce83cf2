"""One MCAP file opened for reading: its channels, message counts and where its messages are.

A complete summary (statistics, a channel record for every counted channel, an index of every chunk) is used
as it is; any other valid file (unchunked, no summary, no index, no statistics, CRCs of 0) is read record by
record once (:func:`smm_bag.mcap_scan.scan_mcap`). Messages are then read block by block (a chunk, or a run
of messages outside chunks): in file order, or in log-time order by merging the blocks.
"""

from __future__ import annotations

import heapq
import mmap
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from mcap.opcode import Opcode
from mcap.records import Channel, Metadata, Schema

from smm_bag.errors import CorruptBagError, TruncatedBagError
from smm_bag.mcap_records import (
    MESSAGE_FIXED,
    PARSE_ERRORS,
    PREFIX,
    chunk_fields,
    decompress,
    read_footer,
    read_summary,
    stream,
)
from smm_bag.mcap_scan import GoodChunk, scan_mcap
from smm_bag.storage import MCAP_MAGIC

__all__ = ["McapFile", "RawMessage"]

RawMessage = tuple[int, int, int, bytes]
"""``(channel id, log time ns, publish time ns, data)``."""


_FAULT_AROUND = 1 << 17
"""Bytes before a block that a page fault in it may map again (twice Linux's ``fault_around_bytes``)."""


@dataclass(frozen=True)
class _Block:
    offset: int
    end: int
    chunk: bool
    start_ns: int
    ordered: bool


class McapFile:
    """The index of one valid MCAP file's bytes.

    Raises:
        CorruptBagError: Bad magic, or a framing check, written CRC or summary check fails.
        TruncatedBagError: The file ends without its footer.
    """

    def __init__(self, data: bytes, path: Path) -> None:
        self.data = data
        self.path = path
        if bytes(data[: len(MCAP_MAGIC)]) != MCAP_MAGIC:
            raise CorruptBagError(f"{path} is not an MCAP file (bad magic {bytes(data[:8])!r})")
        if len(data) < 2 * len(MCAP_MAGIC) or bytes(data[-len(MCAP_MAGIC) :]) != MCAP_MAGIC:
            raise TruncatedBagError(
                f"{path} ends without the MCAP footer (recording killed before it closed the file): "
                "run `smm-bag repair` on the bag"
            )
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.counts: dict[int, int] = {}
        self.span: tuple[int, int] | None = None
        """Earliest and latest log time of the file's messages (ns); None without messages."""
        self.metadata: list[Metadata] = []
        self.blocks: list[_Block] = []
        if not self._from_summary():
            self._from_scan()
        ordered = sorted(self.blocks, key=lambda block: block.offset)
        self._region: dict[int, tuple[int, int]] = {}
        """Per block, the bytes released after reading it: from the previous block's start (at least
        :data:`_FAULT_AROUND` back) to the next block's. The kernel maps a window around each page fault,
        back over blocks already released and the records between blocks (a chunk's message indexes, never
        read): released again with the block's own, or they stay mapped, about 16 bytes per message."""
        for number, block in enumerate(ordered):
            previous = ordered[number - 1].offset if number else 0
            following = ordered[number + 1].offset if number + 1 < len(ordered) else block.end
            self._region[block.offset] = (max(0, min(previous, block.offset - _FAULT_AROUND)), following)

    def _from_summary(self) -> bool:
        """Takes the index from a complete summary; False if there is none."""
        footer = read_footer(self.data)
        try:
            summary = read_summary(self.data, footer) if footer is not None else None
        except PARSE_ERRORS:
            return False
        if footer is None or summary is None or (footer.summary_crc and not summary.checked):
            return False
        stats = summary.statistics
        if stats is None or stats.chunk_count != len(summary.chunk_indexes):
            return False
        counted = {key: count for key, count in stats.channel_message_counts.items() if count}
        if sum(counted.values()) != stats.message_count or (stats.message_count and not stats.chunk_count):
            return False
        if any(key not in summary.channels for key in counted):
            return False
        if any(c.schema_id and c.schema_id not in summary.schemas for c in summary.channels.values()):
            return False
        self.schemas, self.channels, self.counts = dict(summary.schemas), dict(summary.channels), counted
        for index in summary.metadata_indexes:
            body = bytes(self.data[index.offset + 9 : index.offset + index.length])
            try:
                self.metadata.append(Metadata.read(stream(body)))
            except PARSE_ERRORS:
                return False
        for entry in summary.chunk_indexes:
            end = entry.chunk_start_offset + entry.chunk_length
            self.blocks.append(_Block(entry.chunk_start_offset, end, True, entry.message_start_time, False))
        if stats.message_count:
            self.span = (stats.message_start_time, stats.message_end_time)
        self.blocks.sort(key=lambda block: block.offset)
        return True

    def _from_scan(self) -> None:
        scan = scan_mcap(self.data)
        if scan.truncated:
            raise TruncatedBagError(f"{self.path} is truncated: run `smm-bag repair` on the bag")
        if not scan.intact:
            raise CorruptBagError(
                f"{self.path} is damaged ({'; '.join(scan.findings)}): run `smm-bag repair` on the bag"
            )
        self.schemas, self.channels = scan.schemas, scan.channels
        self.metadata = [record for _, _, record in scan.metadata]
        for block in scan.blocks:
            if block.start_ns is None or block.end_ns is None:
                continue
            for key, count in block.counts.items():
                self.counts[key] = self.counts.get(key, 0) + count
            low, high = self.span or (block.start_ns, block.end_ns)
            self.span = (min(low, block.start_ns), max(high, block.end_ns))
            chunk = isinstance(block, GoodChunk)
            end = block.offset + block.length if isinstance(block, GoodChunk) else block.end
            self.blocks.append(_Block(block.offset, end, chunk, block.start_ns, block.ordered))

    def type_name(self, channel: Channel) -> str:
        """``pkg/msg/Type`` of a channel (its schema's name)."""
        schema = self.schemas.get(channel.schema_id)
        return schema.name if schema is not None else channel.metadata.get("type", "")

    def definition(self, type_name: str) -> tuple[str, str] | None:
        """``(encoding, text)`` of the schema named ``type_name`` (None if absent or empty)."""
        for schema in self.schemas.values():
            if schema.name == type_name and schema.data:
                return schema.encoding, bytes(schema.data).decode("utf-8", errors="replace")
        return None

    def messages(self, wanted: set[int] | None, ordered: bool) -> Iterator[RawMessage]:
        """Messages of the channels ``wanted`` (all if None): in file order, or by log time if ``ordered``."""
        if not ordered:
            for block in self.blocks:
                yield from self._block(block, wanted)
            return
        pending = sorted(self.blocks, key=lambda block: (block.start_ns, block.offset))
        heap: list[tuple[int, int, int, RawMessage]] = []
        next_block = 0
        while next_block < len(pending) or heap:
            while next_block < len(pending) and (not heap or pending[next_block].start_ns <= heap[0][0]):
                block = pending[next_block]
                for number, message in enumerate(self._block(block, wanted)):
                    heapq.heappush(heap, (message[1], block.offset, number, message))
                next_block += 1
            if heap:
                yield heapq.heappop(heap)[3]

    def _block(self, block: _Block, wanted: set[int] | None) -> Iterator[RawMessage]:
        if not block.chunk:
            yield from _parse(self.data, block.offset, block.end, wanted, self.path)
            _release(self.data, *self._region[block.offset])
            return
        fields = chunk_fields(self.data, block.offset, len(self.data))
        if fields is None:
            raise CorruptBagError(f"{self.path}: damaged chunk at byte {block.offset}")
        _, size, crc, compression, start, length = fields
        try:
            records = decompress(compression, bytes(self.data[start : start + length]), size)
            _release(self.data, *self._region[block.offset])
        except (*PARSE_ERRORS, RuntimeError, MemoryError) as error:
            raise CorruptBagError(f"{self.path}: damaged chunk ({error})") from None
        if crc and zlib.crc32(records) != crc:
            raise CorruptBagError(f"{self.path}: damaged chunk at byte {block.offset} (CRC mismatch)")
        yield from _parse(records, 0, len(records), wanted, self.path)


def _release(data: bytes, start: int, end: int) -> None:
    """Drops the pages of ``data[start:end]`` from this process's memory when ``data`` is a file mapping.

    Read once, a mapped file's pages would otherwise stay resident (and count in the RSS) until the process
    ends; dropped, a later read maps them again from the page cache. Bounded memory for hour-long bags.
    """
    if not isinstance(data, mmap.mmap) or not hasattr(mmap, "MADV_DONTNEED"):
        return
    page = mmap.PAGESIZE
    first = start - start % page
    last = min(len(data), end)
    if last > first:
        data.madvise(mmap.MADV_DONTNEED, first, last - first)


def _parse(data: bytes, position: int, end: int, wanted: set[int] | None, path: Path) -> Iterator[RawMessage]:
    """The Message records among the records in ``data[position:end]``."""
    unpack_header = PREFIX.unpack_from
    unpack_message = MESSAGE_FIXED.unpack_from
    message = Opcode.MESSAGE
    while position < end:
        if end - position < 9:
            raise CorruptBagError(f"{path}: record header past the end of its chunk")
        opcode, length = unpack_header(data, position)
        body = position + 9
        position = body + length
        if position > end:
            raise CorruptBagError(f"{path}: record past the end of its chunk")
        if opcode != message:
            continue
        try:
            channel, _, log_time, publish_time = unpack_message(data, body)
        except struct.error:
            raise CorruptBagError(f"{path}: message record too short") from None
        if wanted is None or channel in wanted:
            yield channel, log_time, publish_time, bytes(data[body + 22 : position])
