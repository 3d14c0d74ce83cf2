"""``smm-bag repair``: rebuild a bag's damaged MCAP files and ``metadata.yaml`` from the records that check.

Each file is read record by record (:mod:`smm_bag.mcap_scan`). A file is intact if no framing check,
written CRC or summary consistency check fails (absent optional parts are not damage); it is then left
byte for byte. Any other file is rewritten from every record that checks, in order, the original kept as
``<file>.damaged``. docs/BAGS.md ("smm-bag repair") says what is kept and why.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import zstandard
from mcap.records import Channel, Message, Schema
from mcap.writer import CompressionType, Writer

from smm_bag.errors import CorruptBagError, NotABagError, OtherStorageError, UnsalvageableFileError
from smm_bag.mcap_records import chunk_records
from smm_bag.mcap_scan import Damage, FileScan, GoodChunk, chunk_data, scan_mcap
from smm_bag.metadata import (
    METADATA_FILE,
    BagMetadata,
    FileInfo,
    TopicInfo,
    read_metadata,
    recorded_metadata,
    topic_from_channel,
    write_metadata,
)
from smm_bag.repair_report import FileRepair, RepairReport
from smm_bag.storage import is_file_compressed, locate, mapped_file, other_storage

__all__ = ["BACKUP_SUFFIX", "FileRepair", "RepairReport", "repair_backups", "repair_bag"]

BACKUP_SUFFIX = ".damaged"
"""Suffix of the originals repair keeps: ``<file>.damaged``, then ``<file>.damaged.2``, ..."""

_COMPRESSION = {"": CompressionType.NONE, "zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4}


@dataclass
class _File:
    path: Path
    scan: FileScan
    usable: dict[int, Channel]

    def counts(self) -> dict[int, int]:
        counts: dict[int, int] = {}
        for block in self.scan.blocks:
            for channel, count in block.counts.items():
                if channel in self.usable:
                    counts[channel] = counts.get(channel, 0) + count
        return counts

    def info(self) -> FileInfo:
        spans = [
            span
            for block in self.scan.blocks
            for channel, span in block.spans.items()
            if channel in self.usable
        ]
        if not spans:
            return FileInfo(path=self.path.name)
        start, end = min(low for low, _ in spans), max(high for _, high in spans)
        return FileInfo(self.path.name, start, end - start, sum(self.counts().values()))


def _usable(scan: FileScan) -> dict[int, Channel]:
    """Channels whose record and schema record both survive in a copy that checks."""
    return {
        key: channel
        for key, channel in scan.channels.items()
        if channel.schema_id == 0 or channel.schema_id in scan.schemas
    }


def _storage_files(bag: Path, metadata: BagMetadata | None) -> list[Path]:
    def index(path: Path) -> tuple[int, str]:
        tail = path.name.split(".", 1)[0].rsplit("_", 1)[-1]
        return (int(tail) if tail.isdigit() else 0, path.name)

    found = [*bag.glob("*.mcap"), *bag.glob("*.mcap.zstd")]
    on_disk = sorted((path for path in found if path.is_file()), key=index)
    listed = [bag / name for name in metadata.relative_file_paths] if metadata is not None else []
    return listed + [path for path in on_disk if path not in listed]


def _free_name(path: Path) -> Path:
    candidate, number = path.with_name(path.name + BACKUP_SUFFIX), 1
    while candidate.exists():
        number += 1
        candidate = path.with_name(f"{path.name}{BACKUP_SUFFIX}.{number}")
    return candidate


def repair_backups(bag: Path) -> list[Path]:
    """The originals repair kept in the bag folder ``bag`` (``*.damaged``, ``*.damaged.N``), sorted."""
    name = re.compile(rf".+{re.escape(BACKUP_SUFFIX)}(\.[0-9]+)?")
    return sorted(path for path in bag.iterdir() if name.fullmatch(path.name) and path.is_file())


def _fsynced(path: Path) -> None:
    with path.open("rb+") as stream:
        os.fsync(stream.fileno())


def _rewrite(item: _File, data: bytes, serialized: str) -> Path:
    """Writes the kept records of ``item`` to a temporary file next to it, fsynced; returns that file.

    Raises:
        CorruptBagError: The new file does not hold every kept message (the original is then left alone).
    """
    scan = item.scan
    temporary = item.path.with_name(item.path.name + ".repairing")
    kinds = [chunk.compression for chunk in scan.chunks]
    compression = _COMPRESSION[max(set(kinds), key=kinds.count) if kinds else ""]
    with temporary.open("wb") as stream:
        writer = Writer(stream, chunk_size=768 * 1024, compression=compression, enable_data_crcs=True)
        header = scan.header
        library = f"{header.library}; repaired by smm-bag" if header is not None else "repaired by smm-bag"
        writer.start(profile=header.profile if header is not None else "ros2", library=library)
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for key, channel in sorted(item.usable.items()):
            schema: Schema | None = scan.schemas.get(channel.schema_id)
            if schema is not None and schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            channels[key] = writer.register_channel(
                channel.topic,
                channel.message_encoding,
                schemas.get(channel.schema_id, 0),
                dict(channel.metadata),
            )
        for _, _, record in scan.metadata:
            if record.name != "rosbag2":
                writer.add_metadata(record.name, dict(record.metadata))
        writer.add_metadata("rosbag2", {"serialized_metadata": serialized})
        for block in scan.blocks:
            records = (
                chunk_data(data, block) if isinstance(block, GoodChunk) else data[block.offset : block.end]
            )
            for _, message in chunk_records(records):
                if isinstance(message, Message) and message.channel_id in channels:
                    writer.add_message(
                        channels[message.channel_id],
                        message.log_time,
                        message.data,
                        message.publish_time,
                        message.sequence,
                    )
        writer.finish()  # type: ignore[no-untyped-call]
        stream.flush()
        os.fsync(stream.fileno())
    if is_file_compressed(item.path):
        packed = temporary.with_name(temporary.name + ".zstd")
        with temporary.open("rb") as source, packed.open("wb") as target:
            zstandard.ZstdCompressor().copy_stream(source, target)
        temporary.unlink()
        temporary = packed
        _fsynced(temporary)
    with mapped_file(temporary) as written:
        check = scan_mcap(written.data)
    kept = sum(sum(block.counts.values()) for block in check.blocks)
    if not check.intact or kept != sum(item.counts().values()):
        temporary.unlink()
        raise CorruptBagError(f"{item.path}: the rewritten file does not check; the original is left alone")
    return temporary


def _losses(item: _File) -> tuple[int | None, dict[str, int], tuple[tuple[int | None, int | None], ...]]:
    """Lost chunks (None: not known exactly), lost messages per topic and lost log-time ranges."""
    scan, kept = item.scan, {chunk.offset for chunk in item.scan.chunks}
    topics = {key: channel.topic for key, channel in scan.channels.items()}
    lost: dict[str, int] = {}
    counts = item.counts()
    for block in scan.blocks:
        for channel, count in block.counts.items():
            if channel not in item.usable:
                name = f"{topics.get(channel, f'channel {channel}')} (no channel or schema record survives)"
                lost[name] = lost.get(name, 0) + count
    summary = scan.summary
    if summary is not None and summary.statistics is not None:
        for channel, count in summary.statistics.channel_message_counts.items():
            missing = count - counts.get(channel, 0)
            name = topics.get(channel, f"channel {channel}")
            if missing > 0 and channel in item.usable:
                lost[name] = lost.get(name, 0) + missing
    if summary is not None and summary.chunk_indexes:
        gone = [entry for entry in summary.chunk_indexes if entry.chunk_start_offset not in kept]
        return len(gone), lost, tuple((entry.message_start_time, entry.message_end_time) for entry in gone)
    ranges: list[tuple[int | None, int | None]] = []
    places = [damage.start for damage in scan.damage] + ([scan.size] if scan.truncated else [])
    kept_spans = [  # (offset, first, last log time) of the kept messages of each chunk or run
        (block.offset, min(s[0] for s in spans), max(s[1] for s in spans))
        for block in scan.blocks
        if (spans := [span for key, span in block.spans.items() if key in item.usable])
    ]
    for place in places:
        before = [last for offset, _, last in kept_spans if offset < place]
        after = [first for offset, first, _ in kept_spans if offset > place]
        gap = (before[-1] if before else None, after[0] if after else None)
        if gap not in ranges:
            ranges.append(gap)
    return None, lost, tuple(ranges)


def _old_metadata(bag: Path) -> tuple[BagMetadata | None, str]:
    if not (bag / METADATA_FILE).exists():
        return None, "missing"
    try:
        return read_metadata(bag), ""
    except (NotABagError, CorruptBagError) as error:
        return None, f"unreadable ({error})"


def _metadata_from(base: BagMetadata, files: list[_File]) -> BagMetadata:
    """``base`` with the counts, times and files of ``files``; known topics keep their entries as written."""
    known: Mapping[str, TopicInfo] = {topic.name: topic for topic in base.topics}
    topics: dict[str, TopicInfo] = {}
    counts: dict[str, int] = {}
    for item in files:
        file_counts = item.counts()
        for key, channel in item.usable.items():
            previous = known.get(channel.topic)
            schema = item.scan.schemas.get(channel.schema_id)
            topic = topic_from_channel(
                channel.topic, schema.name if schema else "", channel.message_encoding, channel.metadata
            )
            topics.setdefault(channel.topic, previous if previous is not None else topic)
            counts[channel.topic] = counts.get(channel.topic, 0) + file_counts.get(key, 0)
    for name, topic in known.items():
        topics.setdefault(name, topic)
    final = tuple(replace(topic, message_count=counts.get(name, 0)) for name, topic in topics.items())
    return base.with_counts(final, tuple(item.info() for item in files))


def _scan_files(
    paths: list[Path], progress: Callable[[str], None] | None
) -> tuple[list[_File], list[FileRepair]]:
    kept: list[_File] = []
    failed: list[FileRepair] = []
    for path in paths:
        if progress is not None:
            progress(path.name)
        if not path.is_file():
            failed.append(
                FileRepair(path.name, "missing", findings=("listed in metadata.yaml, not on disk",))
            )
            continue
        with mapped_file(path) as mapped:
            scan = scan_mcap(mapped.data)
        if not mapped.complete:
            scan.damage.append(Damage(scan.size, scan.size, "zstd file compression ends early (file cut)"))
        if scan.header is None and not scan.blocks and not scan.channels:
            error = UnsalvageableFileError(
                f"{path}: no MCAP record in it checks ({'; '.join(scan.findings) or 'not MCAP'}); "
                "nothing can be saved, the file is left as it was"
            )
            failed.append(FileRepair(path.name, "unsalvageable", findings=tuple(scan.findings), error=error))
            continue
        kept.append(_File(path, scan, _usable(scan)))
    return kept, failed


def repair_bag(
    path: Path | str, *, backup: bool = True, progress: Callable[[str], None] | None = None
) -> RepairReport:
    """Rebuilds the damaged storage files and ``metadata.yaml`` of a bag from what checks on disk.

    Args:
        path: The bag folder.
        backup: Keep each damaged original as ``<file>.damaged`` and the old ``metadata.yaml`` as
            ``metadata.yaml.damaged``.
        progress: Called with each file name as it is scanned.

    Returns:
        What was found and done; files nothing could be saved from carry an
        :class:`~smm_bag.errors.UnsalvageableFileError` and are left as they were.

    Raises:
        NotABagError: Not a folder, or no MCAP file in it.
        UnsalvageableFileError: No file of the bag holds anything that checks (nothing is changed).
    """
    bag, bare = Path(path), Path(path).is_file()
    old, old_problem, paths = _bag_files(bag)
    files, failed = _scan_files(paths, progress)
    if not files:
        first = next(item.error for item in failed if item.error is not None)
        raise first
    # Without a readable metadata.yaml, the last rosbag2 record of the files is the base.
    agrees = old is not None and _agrees(old, _metadata_from(old, files))
    records = [(record.name, record.metadata) for item in files for _, _, record in item.scan.metadata]
    base = old or recorded_metadata(records) or BagMetadata()
    metadata = _metadata_from(base, files)
    results: dict[str, FileRepair] = {item.path: item for item in failed}
    for item in files:
        counts = item.counts()
        messages = sum(counts.values())
        if item.scan.intact and len(item.usable) == len(item.scan.channels):
            results[item.path.name] = FileRepair(
                item.path.name, "intact", messages, len(item.scan.chunks), checked=_checked(item.scan)
            )
            continue
        with mapped_file(item.path) as mapped:
            temporary = _rewrite(item, mapped.data, metadata.serialized())
        kept = ""
        if backup:
            target = _free_name(item.path)
            item.path.replace(target)
            kept = target.name
        temporary.replace(item.path)  # the new file is complete and fsynced before the original goes
        _sync_directory(item.path.parent)
        lost_chunks, lost, ranges = _losses(item)
        results[item.path.name] = FileRepair(
            item.path.name,
            "repaired",
            messages,
            len(item.scan.chunks),
            item.scan.bad_chunks if lost_chunks is None else lost_chunks,
            lost_chunks is not None,
            lost,
            ranges,
            tuple(item.scan.findings),
            kept,
        )
    reports = tuple(results[p.name] for p in paths)
    rebuilt = [item for item in reports if item.rebuilt]
    note = old_problem or ("" if agrees or old is None else "disagreed with the files")
    lost_total: dict[str, int] = {}
    if old is not None:
        now = {topic.name: topic.message_count for topic in metadata.topics}
        lost_total = {t.name: t.message_count - now.get(t.name, 0) for t in old.topics}
        lost_total = {name: count for name, count in lost_total.items() if count > 0}
    metadata_backup = ""
    rewrite = not bare and not agrees
    if rewrite:
        custom = dict(metadata.custom_data)
        if rebuilt:
            custom["smm.repaired"] = ", ".join(
                f"{item.path}: {item.reason}, {item.messages} messages kept" for item in rebuilt
            )
        metadata = replace(metadata, custom_data=custom)
        current = bag / METADATA_FILE
        if backup and current.exists():
            target = _free_name(current)
            current.replace(target)
            metadata_backup = target.name
        write_metadata(bag, metadata)
    return RepairReport(reports, metadata, note, rewrite, metadata_backup, lost_total, bare)


def _agrees(old: BagMetadata, derived: BagMetadata) -> bool:
    """True if ``metadata.yaml``'s message counts, time range and file list are those of the files."""

    def counts(metadata: BagMetadata) -> dict[str, int]:
        return {topic.name: topic.message_count for topic in metadata.topics if topic.message_count}

    def files(metadata: BagMetadata) -> list[tuple[str, int, int, int]]:
        return [
            (
                info.path,
                info.message_count,
                *((info.starting_time_ns, info.duration_ns) if info.message_count else (0, 0)),
            )
            for info in metadata.files
        ]

    if counts(old) != counts(derived) or old.message_count != derived.message_count:
        return False
    if old.relative_file_paths != derived.relative_file_paths:
        return False
    if old.version >= 5 and files(old) != files(derived):
        return False
    span = (old.starting_time_ns, old.duration_ns)
    return not derived.message_count or span == (derived.starting_time_ns, derived.duration_ns)


def _checked(scan: FileScan) -> str:
    """Which checks an intact file passed (what it holds to check)."""
    crcs = sum(chunk.crc_checked for chunk in scan.chunks)
    parts = [f"{crcs} of {len(scan.chunks)} chunk CRCs written and checking" if scan.chunks else "unchunked"]
    parts.append("summary consistent" if scan.summary is not None else "no summary")
    parts.append("data section CRC checks" if scan.data_crc == "checks" else "no data section CRC written")
    return ", ".join(parts)


def _sync_directory(directory: Path) -> None:
    handle = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(handle)
    finally:
        os.close(handle)


def _not_mcap(bag: Path, storage: str) -> OtherStorageError:
    return OtherStorageError(
        f"{bag}: {storage} storage: repair rebuilds MCAP bags only (`smm-bag convert` writes an MCAP copy)"
    )


def _bag_files(bag: Path) -> tuple[BagMetadata | None, str, list[Path]]:
    """The old metadata (None: missing, unreadable or a bare file), what is wrong with it, the storage files.

    Raises:
        NotABagError: Not a folder or MCAP file, or no MCAP file in the folder.
        OtherStorageError: Another storage (sqlite3, ROS 1).
    """
    if bag.is_file():
        location = locate(bag)
        if location.storage != "mcap":
            raise _not_mcap(bag, location.storage)
        return None, "", list(location.files)
    if not bag.is_dir():
        raise NotABagError(f"{bag} is not a directory (a rosbag2 bag is a folder) nor an MCAP file")
    old, old_problem = _old_metadata(bag)
    if old is not None and old.storage_identifier != "mcap":
        raise _not_mcap(bag, old.storage_identifier)
    paths = _storage_files(bag, old)
    if not any(p.is_file() for p in paths):
        kinds = {kind for item in bag.iterdir() if item.is_file() and (kind := other_storage(item))}
        if kinds:
            raise _not_mcap(bag, ", ".join(sorted(kinds)))
        raise NotABagError(f"{bag} holds no .mcap file: nothing to repair")
    return old, old_problem, paths
