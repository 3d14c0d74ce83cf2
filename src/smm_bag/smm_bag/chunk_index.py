"""The MCAP writer's chunk indexes kept as serialized records until the summary.

mcap-python's ``Writer`` holds one ``ChunkIndex`` object per chunk until ``finish()`` writes the summary:
about 1 KiB each with five channels, 2 chunks a second at the recorder's flush interval, 7 MiB an hour of an
unsplit file. Packed, a chunk costs its record's bytes (73 + 10 per channel in it); the file is the same
(docs/BAGS.md, "Memory of a long recording").
"""

from __future__ import annotations

from collections.abc import Iterator

from mcap.data_stream import RecordBuilder
from mcap.records import ChunkIndex
from mcap.writer import Writer

__all__ = ["PackedChunkIndexes", "pack_chunk_indexes"]

_ATTRIBUTE = "_Writer__chunk_indices"
"""mcap-python's private list of chunk indexes (``Writer.__chunk_indices``), appended and iterated only."""


class _Serialized:
    """Records already serialized, written as they are (what ``ChunkIndex.write`` would write)."""

    def __init__(self, data: bytes) -> None:
        self.data = data

    def write(self, builder: RecordBuilder) -> None:
        """Appends the records to ``builder``."""
        builder.write(self.data)


class PackedChunkIndexes:
    """Chunk index records in one buffer: ``append`` serializes a ``ChunkIndex``; iterating yields them."""

    def __init__(self) -> None:
        self._data = bytearray()
        self._count = 0

    def append(self, index: ChunkIndex) -> None:
        """Serializes ``index`` (the object is not kept)."""
        builder = RecordBuilder()
        index.write(builder)
        self._data += builder.end()  # type: ignore[no-untyped-call]
        self._count += 1

    def __iter__(self) -> Iterator[_Serialized]:
        if self._data:
            yield _Serialized(bytes(self._data))

    def __len__(self) -> int:
        return self._count

    @property
    def nbytes(self) -> int:
        """Bytes of the records held."""
        return len(self._data)


def pack_chunk_indexes(writer: Writer) -> bool:
    """Makes ``writer`` (before its first chunk) keep its chunk indexes packed; False if this mcap cannot."""
    current = getattr(writer, _ATTRIBUTE, None)
    if not isinstance(current, list) or current:
        return False
    setattr(writer, _ATTRIBUTE, PackedChunkIndexes())
    return True
