"""rosbag2 writer: a bag folder with ``metadata.yaml`` (version 9) and MCAP files in rosbag2's conventions.

The conventions of rosbag2_storage_mcap (Jazzy) it follows, and what it adds (flush interval, metadata at
open and at each split, CRCs, loss accounting): docs/BAGS.md, "Format" and "What it adds to rosbag2".
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from importlib.metadata import version as package_version
from pathlib import Path
from types import TracebackType
from typing import IO, Literal

from mcap.writer import CompressionType, Writer

from smm_bag.cdr import stamp_of
from smm_bag.chunk_index import pack_chunk_indexes
from smm_bag.errors import BagExistsError, WriterStateError
from smm_bag.loss import LossAccounting
from smm_bag.metadata import BagMetadata, FileInfo, TopicInfo, write_metadata
from smm_bag.msgdefs import MessageDefinition, message_definition
from smm_bag.qos import QosProfile, dump_profiles

__all__ = ["DEFAULT_FLUSH_INTERVAL_NS", "BagWriter", "WriterOptions"]

DEFAULT_FLUSH_INTERVAL_NS = 500_000_000
"""Default flush interval (ns): at most this much data is lost if the process is killed."""

_MAX_FLUSH_INTERVAL_NS = 1_000_000_000
_MIN_SPLIT_SIZE = 64 * 1024


def _library() -> str:
    try:
        mcap_version = package_version("mcap")
    except Exception:  # pragma: no cover - mcap is installed with this package
        mcap_version = "unknown"
    return f"smm_bag 0.1.0; mcap-python {mcap_version}"


@dataclass(frozen=True)
class WriterOptions:
    """How a bag is written.

    Attributes:
        max_duration_ns: Start a new file when a message is this much later than the file's first (0 = never).
        max_size_bytes: Start a new file when the current one reaches this size (0 = never; else >= 64 KiB).
        compression: ``"none"`` (rosbag2's default) or ``"zstd"`` chunk compression.
        flush_interval_ns: Finish the open chunk and flush it to the OS at least this often (ns), in
            (0, 1 s]: the most data a crash (SIGKILL) can cost.
        chunk_size: Chunk size before a chunk is finished regardless of time (bytes).
        fsync: Also fsync at each flush (survives power loss; slower).
        custom_data: Key/value strings stored in ``custom_data`` (the run manifest).
        ros_distro: ``ros_distro`` of the metadata.
        period_ns: Expected stamp period of the stamp-checked topics (ns).
        stamped_topics: Topics whose stamps are checked for gaps.
        loss_report: Store the loss accounting as ``smm.loss`` at close (a copy of a bag keeps its own).
    """

    max_duration_ns: int = 0
    max_size_bytes: int = 0
    compression: Literal["none", "zstd"] = "none"
    flush_interval_ns: int = DEFAULT_FLUSH_INTERVAL_NS
    chunk_size: int = 768 * 1024
    fsync: bool = False
    custom_data: Mapping[str, str] = field(default_factory=dict)
    ros_distro: str = "jazzy"
    period_ns: int = 1_000_000
    stamped_topics: frozenset[str] = frozenset()
    loss_report: bool = True

    def __post_init__(self) -> None:
        if self.max_duration_ns < 0:
            raise ValueError(f"max_duration_ns must be >= 0, got {self.max_duration_ns}")
        if self.max_size_bytes != 0 and self.max_size_bytes < _MIN_SPLIT_SIZE:
            raise ValueError(f"max_size_bytes must be 0 or >= {_MIN_SPLIT_SIZE}, got {self.max_size_bytes}")
        if self.compression not in ("none", "zstd"):
            raise ValueError(f"compression must be 'none' or 'zstd', got {self.compression!r}")
        if not 0 < self.flush_interval_ns <= _MAX_FLUSH_INTERVAL_NS:
            raise ValueError(f"flush_interval_ns must be in (0, 1e9] ns, got {self.flush_interval_ns}")
        if self.chunk_size <= 0:
            raise ValueError(f"chunk_size must be > 0, got {self.chunk_size}")
        if self.period_ns <= 0:
            raise ValueError(f"period_ns must be > 0, got {self.period_ns}")
        for key, value in self.custom_data.items():
            if not isinstance(key, str) or not isinstance(value, str):
                raise ValueError(f"custom_data must map str to str, got {key!r}: {value!r}")


@dataclass
class _Topic:
    info: TopicInfo
    channel_id: int
    count: int = 0


class BagWriter:
    """Writes one rosbag2 bag (a new folder); use as a context manager or call :meth:`close`.

    Args:
        path: Bag folder to create; must not exist.
        options: Writer options.
        clock: Monotonic clock (ns) deciding when to flush (injectable for tests).

    Raises:
        BagExistsError: ``path`` exists.
    """

    def __init__(
        self,
        path: Path | str,
        options: WriterOptions | None = None,
        *,
        clock: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        self.path = Path(path)
        self.options = options if options is not None else WriterOptions()
        if self.path.exists():
            raise BagExistsError(f"{self.path} exists; rosbag2 never overwrites a bag, choose a new folder")
        self.path.mkdir(parents=True)
        self._clock = clock
        self.loss = LossAccounting(self.options.period_ns, self.options.stamped_topics)
        self._topics: dict[str, _Topic] = {}
        self._custom_data = dict(self.options.custom_data)
        self._files: list[FileInfo] = []
        self._stream: IO[bytes] | None = None
        self._writer: Writer | None = None
        self._schema_ids: dict[str, int] = {}
        self._definitions: dict[str, MessageDefinition] = {}
        self._last_flush_ns = clock()
        self._unflushed = 0
        self._written = 0
        self._flushed = 0
        self._closed = False
        self._open_file()

    # -- files -------------------------------------------------------------------------------------------
    def _file_name(self, index: int) -> str:
        return f"{self.path.name}_{index}.mcap"

    def _open_file(self) -> None:
        name = self._file_name(len(self._files))
        self._stream = (self.path / name).open("wb")
        compression = CompressionType.ZSTD if self.options.compression == "zstd" else CompressionType.NONE
        # Data CRC too: it covers the Header and metadata records, which no chunk CRC does (docs/BAGS.md).
        self._writer = Writer(
            self._stream, chunk_size=self.options.chunk_size, compression=compression, enable_data_crcs=True
        )
        pack_chunk_indexes(self._writer)  # the summary's index in memory: its records' bytes, not objects
        self._writer.start(profile="ros2", library=_library())
        self._files.append(FileInfo(path=name))
        self._schema_ids = {}
        for topic in self._topics.values():
            topic.channel_id = self._register(topic.info)
        self._write_metadata_record()
        self._sync(force=True)
        write_metadata(self.path, self.metadata)

    def _close_file(self) -> None:
        assert self._writer is not None and self._stream is not None
        self._write_metadata_record()
        self._writer.finish()  # type: ignore[no-untyped-call]
        self._stream.flush()
        os.fsync(self._stream.fileno())
        self._stream.close()
        self._writer = None
        self._stream = None

    def _write_metadata_record(self) -> None:
        assert self._writer is not None
        self._writer.add_metadata("rosbag2", {"serialized_metadata": self.metadata.serialized()})

    def _register(self, info: TopicInfo) -> int:
        assert self._writer is not None
        schema_id = self._schema_ids.get(info.type)
        if schema_id is None:
            definition = self._definitions[info.type]
            schema_id = self._writer.register_schema(
                name=info.type, encoding=definition.encoding, data=definition.text.encode("utf-8")
            )
            self._schema_ids[info.type] = schema_id
        return int(
            self._writer.register_channel(
                topic=info.name,
                message_encoding=info.serialization_format,
                schema_id=schema_id,
                metadata={
                    "offered_qos_profiles": dump_profiles(info.offered_qos_profiles),
                    "topic_type_hash": info.type_description_hash,
                },
            )
        )

    # -- public API --------------------------------------------------------------------------------------
    @property
    def metadata(self) -> BagMetadata:
        """The metadata as it stands (counts of what was written so far)."""
        topics = tuple(replace(topic.info, message_count=topic.count) for topic in self._topics.values())
        # Chunk compression is internal to MCAP: rosbag2's compression_format/mode (whole-file or
        # per-message compression by rosbag2_compression) stay empty, as with rosbag2's zstd presets.
        base = BagMetadata(custom_data=dict(self._custom_data), ros_distro=self.options.ros_distro)
        return base.with_counts(topics, tuple(self._files))

    @property
    def topics(self) -> tuple[str, ...]:
        """Topics created so far."""
        return tuple(self._topics)

    def create_topic(
        self,
        name: str,
        type_name: str,
        offered_qos_profiles: Sequence[QosProfile] = (),
        serialization_format: str = "cdr",
        definition: MessageDefinition | None = None,
    ) -> None:
        """Adds a topic (its schema and channel); ``definition`` given, it is stored as it is.

        Raises:
            WriterStateError: The topic exists or the writer is closed.
            UnknownTypeError: No definition is given nor known for ``type_name``.
        """
        self._check_open()
        if name in self._topics:
            raise WriterStateError(f"topic {name} already created")
        if definition is None:
            definition = message_definition(type_name)
        self._definitions.setdefault(definition.type, definition)
        info = TopicInfo(
            name=name,
            type=definition.type,
            serialization_format=serialization_format,
            offered_qos_profiles=tuple(offered_qos_profiles),
            type_description_hash=definition.type_hash,
        )
        self._topics[name] = _Topic(info=info, channel_id=self._register(info))
        self.loss._topic(name)  # listed even if nothing arrives
        write_metadata(self.path, self.metadata)

    def set_custom_data(self, key: str, value: str) -> None:
        """Sets one custom-data entry (stored at the next split and at close)."""
        if not isinstance(key, str) or not isinstance(value, str):
            raise ValueError(f"custom data must be str -> str, got {key!r}: {value!r}")
        self._custom_data[key] = value

    def write(
        self,
        topic: str,
        data: bytes,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        *,
        count_received: bool = True,
    ) -> None:
        """Writes one serialized message (CDR) received at ``log_time_ns`` (ns since the epoch).

        ``count_received=False`` when the caller counted the message as received itself (a recorder
        counting in its subscription callback, so that messages it drops show as lost).

        Raises:
            WriterStateError: Unknown topic or the writer is closed.
        """
        self._check_open()
        entry = self._topics.get(topic)
        if entry is None:
            raise WriterStateError(f"write on topic {topic} before create_topic")
        if log_time_ns < 0:
            raise ValueError(f"log_time_ns must be >= 0, got {log_time_ns}")
        if self._should_split(log_time_ns):
            self.split()
        assert self._writer is not None
        self._writer.add_message(
            channel_id=entry.channel_id,
            log_time=log_time_ns,
            data=data,
            publish_time=log_time_ns if publish_time_ns is None else publish_time_ns,
        )
        entry.count += 1
        current = self._files[-1]
        start = min(current.starting_time_ns, log_time_ns)
        end = max(
            current.starting_time_ns + current.duration_ns if current.message_count else log_time_ns,
            log_time_ns,
        )
        self._files[-1] = FileInfo(current.path, start, end - start, current.message_count + 1)
        stamp = stamp_of(entry.info.type, data) if topic in self.loss.stamped_topics else None
        if count_received:
            self.loss.received(topic)
        self.loss.written(topic, stamp)
        self._unflushed += 1
        self._written += 1
        self.tick()

    def tick(self) -> None:
        """Flushes if the flush interval has passed since the last flush (call it from a timer too)."""
        if self._unflushed and self._clock() - self._last_flush_ns >= self.options.flush_interval_ns:
            self._sync(force=True)

    def flush(self) -> None:
        """Finishes the open chunk and hands everything to the OS now."""
        self._check_open()
        self._sync(force=True)

    def _sync(self, *, force: bool) -> None:
        if self._writer is None or self._stream is None or not force:
            return
        self._writer.flush()  # type: ignore[no-untyped-call]
        if self.options.fsync:
            os.fsync(self._stream.fileno())
        self._last_flush_ns = self._clock()
        self._unflushed = 0
        self._flushed = self._written

    def _should_split(self, log_time_ns: int) -> bool:
        current = self._files[-1]
        if current.message_count == 0:
            return False
        if (
            self.options.max_duration_ns
            and log_time_ns - current.starting_time_ns >= self.options.max_duration_ns
        ):
            return True
        return bool(
            self.options.max_size_bytes
            and self._stream is not None
            and self._stream.tell() >= self.options.max_size_bytes
        )

    def split(self) -> None:
        """Closes the current file and continues in a new one (metadata.yaml rewritten)."""
        self._check_open()
        self._close_file()
        self._open_file()

    def close(self) -> BagMetadata:
        """Finishes the last file and writes the final ``metadata.yaml``; returns the metadata."""
        if self._closed:
            return self.metadata
        if self.options.loss_report:
            self._custom_data["smm.loss"] = self.loss.to_json()
        self._close_file()
        self._closed = True
        metadata = self.metadata
        write_metadata(self.path, metadata)
        return metadata

    @property
    def flushed_count(self) -> int:
        """Messages handed to the OS so far (what survives if the process is killed now)."""
        return self._flushed

    @property
    def closed(self) -> bool:
        """True after :meth:`close`."""
        return self._closed

    def _check_open(self) -> None:
        if self._closed:
            raise WriterStateError(f"bag {self.path} is closed")

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.close()
