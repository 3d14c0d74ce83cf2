"""``smm-bag repair``: rebuild MCAP summaries and indexes and ``metadata.yaml`` from what is on disk.

A recording killed (SIGKILL, power loss) leaves its last file without summary, index and footer, and
``metadata.yaml`` as written at open or at the last split. Every complete record up to the damage is kept:
schemas, channels and the messages of every complete chunk (the writer finishes a chunk at least every
flush interval, so the loss is at most that interval). A damaged file is rewritten next to itself and the
original kept as ``<file>.damaged`` (unless ``backup=False``).
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import yaml
from mcap.exceptions import McapError
from mcap.reader import SeekingReader
from mcap.records import Channel, DataEnd, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from smm_bag.errors import BagError, CorruptBagError, NotABagError, TruncatedBagError
from smm_bag.metadata import (
    BagMetadata,
    FileInfo,
    TopicInfo,
    parse_metadata,
    read_metadata,
    write_metadata,
)
from smm_bag.qos import load_profiles
from smm_bag.reader import check_mcap_file

__all__ = ["FileRepair", "RepairReport", "repair_bag"]

_INDEX = re.compile(r"_(\d+)\.mcap$")


@dataclass(frozen=True)
class FileRepair:
    """What repair did to one storage file.

    Attributes:
        path: File name inside the bag.
        rebuilt: True if the file was rewritten (it was truncated or had no summary).
        messages: Messages in the file after repair.
        dropped_bytes: Bytes after the last complete record (lost data), 0 for an intact file.
        backup: Name of the kept original, if any.
        reason: Why the file needed repair (empty if intact).
    """

    path: str
    rebuilt: bool
    messages: int
    dropped_bytes: int
    backup: str
    reason: str


@dataclass(frozen=True)
class RepairReport:
    """Result of :func:`repair_bag`: per-file actions and the rewritten metadata."""

    files: tuple[FileRepair, ...]
    metadata: BagMetadata

    @property
    def changed(self) -> bool:
        """True if any file was rebuilt."""
        return any(item.rebuilt for item in self.files)


@dataclass
class _Content:
    schemas: dict[int, Schema]
    channels: dict[int, Channel]
    counts: dict[int, int]
    first_ns: int | None
    last_ns: int | None
    metadata_records: list[Metadata]
    good_bytes: int


def _scan(path: Path, on_message: Callable[[Message], None] | None = None) -> _Content:
    """Reads records in order until the end or the first damaged one."""
    content = _Content({}, {}, {}, None, None, [], 0)
    with path.open("rb") as stream:
        reader = StreamReader(stream, validate_crcs=True)
        records: Iterator[object] = iter(reader.records)
        while True:
            try:
                record = next(records)
            except StopIteration:
                break
            except (
                McapError,
                ValueError,
                EOFError,
                OSError,
                MemoryError,
                IndexError,
                KeyError,
                struct.error,
            ):
                break
            if isinstance(record, Schema):
                content.schemas.setdefault(record.id, record)
            elif isinstance(record, Channel):
                content.channels.setdefault(record.id, record)
            elif isinstance(record, Message):
                content.counts[record.channel_id] = content.counts.get(record.channel_id, 0) + 1
                time = record.log_time
                content.first_ns = time if content.first_ns is None else min(content.first_ns, time)
                content.last_ns = time if content.last_ns is None else max(content.last_ns, time)
                if on_message is not None:
                    on_message(record)
            elif isinstance(record, Metadata):
                content.metadata_records.append(record)
            elif isinstance(record, DataEnd):
                content.good_bytes = stream.tell()
                break
            # Only what the reader consumed entirely counts as good (a chunk is consumed whole).
            content.good_bytes = stream.tell() if not isinstance(record, Message) else content.good_bytes
    return content


def _storage_files(bag: Path, metadata: BagMetadata | None) -> list[Path]:
    on_disk = sorted(
        (path for path in bag.glob("*.mcap")),
        key=lambda p: int(m.group(1)) if (m := _INDEX.search(p.name)) else 0,
    )
    if metadata is None:
        return on_disk
    listed = [bag / name for name in metadata.relative_file_paths]
    return listed + [path for path in on_disk if path not in listed]


def _intact(path: Path) -> bool:
    try:
        check_mcap_file(path)
        with path.open("rb") as stream:
            summary = SeekingReader(stream).get_summary()
        return summary is not None and summary.statistics is not None
    except (BagError, McapError, ValueError, EOFError, OSError):
        return False


def _rewrite(path: Path, content: _Content, backup: bool, serialized: str) -> str:
    temporary = path.with_name(path.name + ".repairing")
    with temporary.open("wb") as stream:
        writer = Writer(stream, compression=CompressionType.NONE)
        header_profile, library = "ros2", "smm_bag repair"
        writer.start(profile=header_profile, library=library)
        schema_ids = {
            old: writer.register_schema(name=s.name, encoding=s.encoding, data=s.data)
            for old, s in sorted(content.schemas.items())
        }
        channel_ids = {
            old: writer.register_channel(
                topic=c.topic,
                message_encoding=c.message_encoding,
                schema_id=schema_ids.get(c.schema_id, 0),
                metadata=dict(c.metadata),
            )
            for old, c in sorted(content.channels.items())
        }
        writer.add_metadata("rosbag2", {"serialized_metadata": serialized})

        def copy(message: Message) -> None:
            writer.add_message(
                channel_id=channel_ids[message.channel_id],
                log_time=message.log_time,
                data=message.data,
                publish_time=message.publish_time,
                sequence=message.sequence,
            )

        _scan(path, copy)
        writer.finish()  # type: ignore[no-untyped-call]
    kept = ""
    if backup:
        kept = path.name + ".damaged"
        path.replace(path.with_name(kept))
    temporary.replace(path)
    return kept


def _old_metadata(bag: Path) -> BagMetadata | None:
    try:
        return read_metadata(bag)
    except (NotABagError, CorruptBagError):
        return None


def _record_metadata(records: list[Metadata]) -> BagMetadata | None:
    for record in reversed(records):
        text = record.metadata.get("serialized_metadata") if record.name == "rosbag2" else None
        if text:
            try:
                return parse_metadata(yaml.safe_load(text), "rosbag2 metadata record")
            except (CorruptBagError, yaml.YAMLError):
                continue
    return None


def repair_bag(
    path: Path | str, *, backup: bool = True, progress: Callable[[str], None] | None = None
) -> RepairReport:
    """Rebuilds damaged storage files and ``metadata.yaml`` of a bag from what is on disk.

    Args:
        path: The bag folder.
        backup: Keep each damaged original as ``<file>.damaged``.
        progress: Called with each file name as it is processed.

    Returns:
        What was done.

    Raises:
        NotABagError: Not a folder, or no MCAP file in it.
        CorruptBagError: A file is not MCAP at all (bad magic).
    """
    bag = Path(path)
    if not bag.is_dir():
        raise NotABagError(f"{bag} is not a directory (a rosbag2 bag is a folder)")
    old = _old_metadata(bag)
    files = _storage_files(bag, old)
    if not files:
        raise NotABagError(f"{bag} holds no .mcap file: nothing to repair")
    scans: list[tuple[Path, _Content, bool, str]] = []
    for file in files:
        if progress is not None:
            progress(file.name)
        if not file.is_file():
            continue
        with file.open("rb") as stream:
            if stream.read(8) != b"\x89MCAP0\r\n":
                raise CorruptBagError(f"{file} is not an MCAP file (bad magic); it cannot be repaired")
        intact = _intact(file)
        reason = ""
        if not intact:
            try:
                check_mcap_file(file)
                reason = "no readable summary"
            except TruncatedBagError:
                reason = "truncated (no footer)"
        scans.append((file, _scan(file), intact, reason))

    recorded = next(
        (m for _, c, _, _ in reversed(scans) if (m := _record_metadata(c.metadata_records))), None
    )
    base = old if old is not None else recorded if recorded is not None else BagMetadata()
    metadata = _metadata_from(base, scans)
    reports = []
    for file, content, intact, reason in scans:
        messages = sum(content.counts.values())
        if intact:
            reports.append(FileRepair(file.name, False, messages, 0, "", ""))
            continue
        dropped = file.stat().st_size - content.good_bytes
        kept = _rewrite(file, content, backup, metadata.serialized())
        reports.append(FileRepair(file.name, True, messages, dropped, kept, reason))
    if any(item.rebuilt for item in reports) or old is None or _disagrees(old, metadata):
        custom = dict(metadata.custom_data)
        if any(item.rebuilt for item in reports):
            custom["smm.repaired"] = ", ".join(
                f"{item.path}: {item.reason}, {item.messages} messages kept, "
                f"{item.dropped_bytes} bytes dropped"
                for item in reports
                if item.rebuilt
            )
        metadata = replace(metadata, custom_data=custom)
        write_metadata(bag, metadata)
    return RepairReport(tuple(reports), metadata)


def _disagrees(old: BagMetadata, new: BagMetadata) -> bool:
    counts = {topic.name: topic.message_count for topic in old.topics}
    return counts != {topic.name: topic.message_count for topic in new.topics} or (
        old.relative_file_paths != new.relative_file_paths
    )


def _metadata_from(base: BagMetadata, scans: list[tuple[Path, _Content, bool, str]]) -> BagMetadata:
    known: Mapping[str, TopicInfo] = {topic.name: topic for topic in base.topics}
    topics: dict[str, TopicInfo] = {}
    counts: dict[str, int] = {}
    files = []
    for file, content, _, _ in scans:
        for channel_id, channel in content.channels.items():
            schema = content.schemas.get(channel.schema_id)
            previous = known.get(channel.topic)
            if channel.topic not in topics:
                qos = channel.metadata.get("offered_qos_profiles")
                topics[channel.topic] = TopicInfo(
                    name=channel.topic,
                    type=schema.name if schema is not None else (previous.type if previous else ""),
                    serialization_format=channel.message_encoding,
                    offered_qos_profiles=tuple(load_profiles(qos))
                    if qos is not None
                    else (previous.offered_qos_profiles if previous else ()),
                    type_description_hash=channel.metadata.get(
                        "topic_type_hash", previous.type_description_hash if previous else ""
                    ),
                )
            counts[channel.topic] = counts.get(channel.topic, 0) + content.counts.get(channel_id, 0)
        count = sum(content.counts.values())
        if content.first_ns is None or content.last_ns is None:
            files.append(FileInfo(path=file.name))
        else:
            files.append(FileInfo(file.name, content.first_ns, content.last_ns - content.first_ns, count))
    for name, topic in known.items():
        topics.setdefault(name, replace(topic, message_count=0))
    final = tuple(replace(topic, message_count=counts.get(name, 0)) for name, topic in topics.items())
    return base.with_counts(final, tuple(files))
