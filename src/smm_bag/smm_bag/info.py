"""``smm-bag info``: what ``ros2 bag info`` (Jazzy) prints, plus the run manifest and the loss report.

The layout follows rosbag2_py/src/rosbag2_py/format_bag_metadata.cpp (Jazzy).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from smm_bag.metadata import METADATA_FILE, BagMetadata, service_event
from smm_bag.reader import BagReader
from smm_bag.repair import BACKUP_SUFFIX, repair_backups

__all__ = ["bag_size", "format_info"]

_INDENT = " " * 19
_NS = 1_000_000_000
_NO_TYPE = "(none)"
"""Shown for a channel without schema (schema id 0), which rosbag2 cannot read at all."""


def bag_size(path: Path, metadata: BagMetadata) -> int:
    """Bytes of the bag's own files: ``metadata.yaml`` and the storage files it lists (no backups).

    ``path`` is the bag folder, or the one storage file given instead of it.
    """
    if path.is_file():
        return path.stat().st_size
    paths = [path / METADATA_FILE, *(path / name for name in metadata.relative_file_paths)]
    return sum(item.stat().st_size for item in paths if item.is_file())


def _backups_line(directory: Path) -> str | None:
    """``Repair backups: N files, size (*.damaged)`` if ``smm-bag repair`` kept originals here."""
    backups = repair_backups(directory)
    if not backups:
        return None
    size = sum(path.stat().st_size for path in backups)
    files = "1 file" if len(backups) == 1 else f"{len(backups)} files"
    return f"Repair backups: {files}, {_size(size)} (*{BACKUP_SUFFIX}; not in the bag size)"


def _size(size: int) -> str:
    value = float(size)
    units = ("B", "KiB", "MiB", "GiB", "TiB")
    index = 0
    while value >= 1024 and index < 4:
        value /= 1024
        index += 1
    return f"{value:.0f} {units[index]}" if index == 0 else f"{value:.1f} {units[index]}"


def _seconds(ns: int) -> str:
    return f"{ns // _NS}.{ns % _NS:09d}"


def _time_point(ns: int) -> str:
    local = time.localtime(ns // _NS)
    day = f"{local.tm_mday:2d}"
    clock = time.strftime("%H:%M:%S", local)
    return f"{time.strftime('%b', local)} {day} {local.tm_year} {clock}.{ns % _NS:09d} ({_seconds(ns)})"


def format_metadata(metadata: BagMetadata, size: int) -> str:
    """The ``ros2 bag info`` text of a bag's metadata."""
    lines = [""]
    paths = metadata.relative_file_paths
    lines.append("Files:             " + (paths[0] if paths else ""))
    lines.extend(_INDENT + path for path in paths[1:])
    lines.append(f"Bag size:          {_size(size)}")
    lines.append(f"Storage id:        {metadata.storage_identifier}")
    lines.append(f"ROS Distro:        {metadata.ros_distro or 'unknown'}")
    lines.append(f"Duration:          {_seconds(metadata.duration_ns)}s")
    lines.append(f"Start:             {_time_point(metadata.starting_time_ns)}")
    lines.append(f"End:               {_time_point(metadata.starting_time_ns + metadata.duration_ns)}")
    services = [(t, found) for t in metadata.topics if (found := service_event(t.name, t.type)) is not None]
    events = sum(t.message_count for t, _ in services)
    lines.append(f"Messages:          {metadata.message_count - events}")
    topics = [
        f"Topic: {t.name} | Type: {t.type or _NO_TYPE} | Count: {t.message_count} | "
        f"Serialization Format: {t.serialization_format}"
        for t in metadata.topics
        if service_event(t.name, t.type) is None
    ]
    lines.append("Topic information: " + (topics[0] if topics else ""))
    lines.extend(_INDENT + line for line in topics[1:])
    lines.append(f"Service:           {len(services)}")
    described = [
        f"Service: {name} | Type: {kind} | Event Count: {t.message_count} | "
        f"Serialization Format: {t.serialization_format}"
        for t, (name, kind) in services
    ]
    lines.append("Service information: " + (described[0] if described else ""))
    lines.extend(_INDENT + "  " + line for line in described[1:])
    return "\n".join(lines)


def format_info(path: Path) -> str:
    """``ros2 bag info`` text of a bag (checked by opening it), then repair backups, manifest and loss report.

    Raises:
        BagError: The bag cannot be opened (see :class:`smm_bag.reader.BagReader`).
    """
    with BagReader(path) as reader:
        metadata = reader.metadata
    text = format_metadata(metadata, bag_size(path, metadata))
    custom = {
        key: value for key, value in metadata.custom_data.items() if key not in ("smm.parameters", "smm.loss")
    }
    backups = _backups_line(path) if path.is_dir() else None
    extra = [backups] if backups else []
    if custom:
        extra.append("Custom data:")
        extra.extend(f"  {key}: {value}" for key, value in sorted(custom.items()))
    loss = metadata.custom_data.get("smm.loss")
    if loss:
        extra.append("Recorder loss accounting (received / written / lost, stamp gaps):")
        try:
            topics = json.loads(loss).get("topics", {})
        except json.JSONDecodeError:
            topics = {}
        for topic, counters in sorted(topics.items()):
            extra.append(
                f"  {topic}: {counters.get('received')} / {counters.get('written')} / "
                f"{counters.get('lost')}, "
                f"gaps {counters.get('stamp_gaps')} ({counters.get('stamp_missing')} samples)"
            )
    return text + ("\n" + "\n".join(extra) if extra else "")
