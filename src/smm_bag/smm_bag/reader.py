"""rosbag2 bag reader with typed errors: not a bag, other storage, truncated, corrupt, missing topics.

Reads a bag folder or a bare ``.mcap`` / ``.db3`` file (or its ``.zstd``; :mod:`smm_bag.storage`), every
valid MCAP file shape (:mod:`smm_bag.mcap_file`), sqlite3 files (:mod:`smm_bag.sqlite_file`), and checks
``metadata.yaml``'s counts against the files.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass, replace
from pathlib import Path
from types import TracebackType

import zstandard

from smm_bag.errors import CorruptBagError, MissingTopicsError, TruncatedBagError
from smm_bag.mcap_file import McapFile
from smm_bag.metadata import BagMetadata, FileInfo, TopicInfo, recorded_metadata, topic_from_channel
from smm_bag.sqlite_file import SqliteFile
from smm_bag.storage import MCAP_MAGIC, is_file_compressed, locate, mapped_file, plain_file

__all__ = ["MCAP_MAGIC", "BagMessage", "BagReader"]


@dataclass(frozen=True)
class BagMessage:
    """One stored message: topic, type (``pkg/msg/Type``), receive and send times (ns), CDR bytes."""

    topic: str
    type: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes


class BagReader:
    """Opens a rosbag2 MCAP or sqlite3 bag (folder or bare file) and checks it against its ``metadata.yaml``.

    Args:
        path: The bag folder, or one ``.mcap`` / ``.db3`` file (or its ``.zstd``).

    Raises:
        NotABagError: Neither a bag folder nor a storage file; a folder without ``metadata.yaml``.
        OtherStorageError: A storage other than MCAP and sqlite3 (ROS 1).
        TruncatedBagError: A file lacks its footer (``smm-bag repair`` rebuilds it).
        CorruptBagError: Bad magic, damaged records, or counts differing from ``metadata.yaml``.
    """

    def __init__(self, path: Path | str) -> None:
        self.path = Path(path)
        location = locate(self.path)
        self._stack = ExitStack()
        self._files: list[McapFile | SqliteFile] = []
        try:
            for file in location.files:
                if not file.is_file():
                    raise CorruptBagError(f"storage file {file} listed in metadata.yaml is missing")
                self._files.append(self._open(file, location.storage))
            if location.metadata is None:
                self.metadata = _derived_metadata(self._files, location.storage)
            else:
                self.metadata = location.metadata
                self._check_counts()
            self._decode = _message_decoder(self.metadata)
        except BaseException:
            self.close()
            raise

    def _open(self, file: Path, storage: str) -> McapFile | SqliteFile:
        if storage == "sqlite3":
            plain, complete = self._stack.enter_context(plain_file(file))
            if not complete:
                raise TruncatedBagError(f"{file}: its zstd file compression ends early (file cut)")
            opened = SqliteFile(plain, file)
            self._stack.callback(opened.close)
            return opened
        mapped = self._stack.enter_context(mapped_file(file))
        if not mapped.complete:
            raise TruncatedBagError(f"{file}: its zstd file compression ends early (file cut)")
        return McapFile(mapped.data, file)

    def _stored(self) -> dict[str, int]:
        stored: dict[str, int] = {}
        for file in self._files:
            for key, count in file.counts.items():
                channel = file.channels.get(key)
                topic = channel.topic if channel is not None else f"channel {key}"
                stored[topic] = stored.get(topic, 0) + count
        return stored

    def _check_counts(self) -> None:
        stored = self._stored()
        for info in self.metadata.topics:
            if stored.get(info.name, 0) != info.message_count:
                raise CorruptBagError(
                    f"{self.path}: metadata.yaml says {info.message_count} messages on {info.name}, "
                    f"the storage files hold {stored.get(info.name, 0)}"
                )
        listed = {info.name for info in self.metadata.topics}
        extra = sorted(name for name, count in stored.items() if count and name not in listed)
        if extra:
            raise CorruptBagError(f"{self.path}: storage holds topics missing from metadata.yaml: {extra}")

    @property
    def topics(self) -> dict[str, str]:
        """Topic name -> type name."""
        return {topic.name: topic.type for topic in self.metadata.topics}

    @property
    def message_count(self) -> int:
        """Messages in the bag."""
        return self.metadata.message_count

    def stored_definition(self, type_name: str) -> tuple[str, str] | None:
        """``(encoding, text)`` of the definition of ``type_name`` the storage files hold (None: none)."""
        for file in self._files:
            found = file.definition(type_name)
            if found is not None:
                return found
        return None

    def require(self, topics: Iterable[str]) -> None:
        """Raises :class:`MissingTopicsError` naming every topic of ``topics`` without messages."""
        counts = {topic.name: topic.message_count for topic in self.metadata.topics}
        missing = [topic for topic in topics if counts.get(topic, 0) == 0]
        if missing:
            raise MissingTopicsError(
                f"{self.path} has no messages on {', '.join(missing)} (topics: {', '.join(sorted(counts))})"
            )

    def messages(
        self,
        topics: Iterable[str] | None = None,
        *,
        ordered: bool = True,
        progress: Callable[[int], None] | None = None,
    ) -> Iterator[BagMessage]:
        """Messages of ``topics`` (all if None), file after file; by log time if ``ordered``, else as stored.

        Args:
            topics: Topic names to read.
            ordered: Sort by log time within each file (files are in time order already).
            progress: Called with the number of messages read so far, every 10 000 messages.

        Raises:
            CorruptBagError: A chunk fails its CRC or cannot be decoded.
        """
        wanted = None if topics is None else set(topics)
        read = 0
        for file in self._files:
            channels = {
                key: (channel.topic, file.type_name(channel))
                for key, channel in file.channels.items()
                if wanted is None or channel.topic in wanted
            }
            for key, log_time, publish_time, data in file.messages(set(channels), ordered):
                topic, type_name = channels[key]
                yield BagMessage(topic, type_name, log_time, publish_time, self._decode(data))
                read += 1
                if progress is not None and read % 10_000 == 0:
                    progress(read)
        if progress is not None:
            progress(read)

    def raw_messages(self, topics: Iterable[str]) -> Iterator[tuple[str, int, bytes]]:
        """``(topic, log time ns, CDR bytes)`` of ``topics`` in stored order (no record objects).

        Raises:
            CorruptBagError: A chunk fails its CRC, cannot be decompressed or is malformed.
        """
        wanted = set(topics)
        for file in self._files:
            names = {key: c.topic for key, c in file.channels.items() if c.topic in wanted}
            if names:
                for key, log_time, _, data in file.messages(set(names), ordered=False):
                    yield names[key], log_time, self._decode(data)

    def close(self) -> None:
        """Closes the storage files (and removes their decompressed copies)."""
        self._files = []
        self._stack.close()

    def __enter__(self) -> BagReader:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.close()


def _message_decoder(metadata: BagMetadata) -> Callable[[bytes], bytes]:
    """What turns a stored message into its CDR bytes: rosbag2's message compression undone (zstd only).

    Raises:
        CorruptBagError: A message compression other than zstd.
    """
    if metadata.compression_mode.lower() != "message":
        return bytes
    if metadata.compression_format != "zstd":
        raise CorruptBagError(f"message compression {metadata.compression_format!r} is not supported (zstd)")
    decompressor = zstandard.ZstdDecompressor()

    def decode(data: bytes) -> bytes:
        try:
            return bytes(decompressor.decompressobj().decompress(data))
        except zstandard.ZstdError as error:
            raise CorruptBagError(f"a compressed message does not decompress ({error})") from None

    return decode


def _derived_metadata(files: list[McapFile | SqliteFile], storage: str) -> BagMetadata:
    """Metadata of bare storage files, from their channels and counts (what ``ros2 bag info file`` shows)."""
    recorded = recorded_metadata([(r.name, r.metadata) for file in files for r in file.metadata])
    distro = next((f.ros_distro for f in files if isinstance(f, SqliteFile) and f.ros_distro), "")
    base = recorded if recorded is not None else BagMetadata(ros_distro=distro)
    base = replace(base, storage_identifier=storage)
    topics: dict[str, TopicInfo] = {}
    counts: dict[str, int] = {}
    infos = []
    for file in files:
        for key, channel in file.channels.items():
            topics.setdefault(
                channel.topic,
                topic_from_channel(
                    channel.topic, file.type_name(channel), channel.message_encoding, channel.metadata
                ),
            )
            counts[channel.topic] = counts.get(channel.topic, 0) + file.counts.get(key, 0)
        start, end = file.span if file.span is not None else (0, 0)
        messages = sum(file.counts.values())
        name = file.path.name
        infos.append(FileInfo(name, start, end - start, messages) if messages else FileInfo(name))
    final = tuple(replace(topic, message_count=counts[name]) for name, topic in topics.items())
    compressed = any(is_file_compressed(file.path) for file in files)
    metadata = base.with_counts(final, tuple(infos))
    if compressed:
        metadata = replace(metadata, compression_format="zstd", compression_mode="FILE")
    return metadata
