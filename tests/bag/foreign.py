"""Bags of shapes our writer never makes, written with the ``mcap`` library, and an independent reader.

``rewrite`` copies a bag's messages (read with ``mcap``'s own reader) into MCAP files of a chosen shape and
writes ``metadata.yaml`` by hand in a chosen version (4 to 9, each with its own QoS encoding), or none (a bare
file). ``stream_messages`` reads records in order with ``mcap``'s StreamReader: the independent count.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
import zstandard
from mcap.reader import make_reader
from mcap.records import Channel, Message
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, IndexType, Writer

Key = tuple[str, int, bytes]
"""A message as (topic, log time ns, data)."""

QOS_V9 = {
    "history": "keep_last",
    "depth": 10,
    "reliability": "reliable",
    "durability": "volatile",
    "deadline": {"sec": 9223372036, "nsec": 854775807},
    "lifespan": {"sec": 9223372036, "nsec": 854775807},
    "liveliness": "manual_by_topic",
    "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
    "avoid_ros_namespace_conventions": False,
}
QOS_V8 = {
    **QOS_V9,
    "history": 1,
    "reliability": 1,
    "durability": 2,
    "liveliness": 3,  # rmw: 0 system default, 1 automatic, 2 manual by node, 3 manual by topic
    "deadline": {"sec": 2147483647, "nsec": 4294967295},  # a Foxy-era infinity
}


@dataclass(frozen=True)
class Shape:
    """How the MCAP files are written (the ``mcap`` Writer's options, plus file compression and splits)."""

    chunked: bool = True
    compression: str = "zstd"
    crcs: bool = True
    statistics: bool = True
    indexes: bool = True
    summary_channels: bool = True
    files: int = 1
    file_compression: bool = False
    message_compression: bool = False

    @property
    def name(self) -> str:
        parts = [("chunked-" + (self.compression or "none")) if self.chunked else "unchunked"]
        parts += [] if self.crcs else ["no-crc"]
        parts += [] if self.statistics else ["no-statistics"]
        parts += [] if self.indexes else ["no-index"]
        parts += [] if self.summary_channels else ["no-summary-channels"]
        parts += [f"{self.files}-files"] if self.files > 1 else []
        parts += ["zstd-file"] if self.file_compression else []
        parts += ["zstd-messages"] if self.message_compression else []
        return "+".join(parts)


def source_messages(bag: Path) -> tuple[list[tuple[Channel, Any, Message]], dict[str, Any]]:
    """Every message of a bag's files read by ``mcap`` (channel, schema, message); the run's custom data."""
    found = []
    for path in sorted(bag.glob("*.mcap")):
        with path.open("rb") as stream:
            for schema, channel, message in make_reader(stream).iter_messages(log_time_order=False):
                found.append((channel, schema, message))
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return found, dict(info.get("custom_data") or {})


def _write_mcap(path: Path, items: list[tuple[Channel, Any, Message]], shape: Shape) -> None:
    compression = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "": CompressionType.NONE}
    with path.open("wb") as stream:
        writer = Writer(
            stream,
            chunk_size=2048,
            compression=compression[shape.compression],
            index_types=IndexType.ALL if shape.indexes else IndexType.NONE,
            repeat_channels=shape.summary_channels,
            repeat_schemas=shape.summary_channels,
            use_chunking=shape.chunked,
            use_statistics=shape.statistics,
            use_summary_offsets=shape.indexes,
            enable_crcs=shape.crcs,
        )
        writer.start("ros2", "tests (mcap Python writer)")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for channel, schema, message in items:
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                metadata = {"offered_qos_profiles": yaml.safe_dump([QOS_V9]), "topic_type_hash": ""}
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id], metadata
                )
            data = message.data
            if shape.message_compression:  # rosbag2's compression_mode "message": each message a zstd frame
                data = zstandard.ZstdCompressor().compress(data)
            writer.add_message(channels[channel.id], message.log_time, data, message.publish_time)
        writer.finish()  # type: ignore[no-untyped-call]
    if shape.file_compression:
        packed = path.with_name(path.name + ".zstd")
        packed.write_bytes(zstandard.ZstdCompressor().compress(path.read_bytes()))
        path.unlink()


def _qos(version: int) -> Any:
    return [QOS_V9] if version >= 9 else yaml.safe_dump([QOS_V8])


def metadata_yaml(
    version: int,
    files: list[tuple[str, list[Key]]],
    types: dict[str, str],
    custom: dict[str, str],
    mode: str = "",
) -> dict[str, Any]:
    """``metadata.yaml`` as rosbag2 writes the given version (fields of later versions left out)."""
    every = [key for _, keys in files for key in keys]
    counts: dict[str, int] = {}
    for topic, _, _ in every:
        counts[topic] = counts.get(topic, 0) + 1
    start = min(time for _, time, _ in every)
    topics = []
    for topic, count in counts.items():
        meta: dict[str, Any] = {
            "name": topic,
            "type": types[topic],
            "serialization_format": "cdr",
            "offered_qos_profiles": _qos(version),
        }
        if version >= 7:
            meta["type_description_hash"] = ""
        topics.append({"topic_metadata": meta, "message_count": count})
    node: dict[str, Any] = {
        "version": version,
        "storage_identifier": "mcap",
        "duration": {"nanoseconds": max(time for _, time, _ in every) - start},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": len(every),
        "topics_with_message_count": topics,
        "compression_format": "zstd" if mode else "",
        "compression_mode": mode,
        "relative_file_paths": [name for name, _ in files],
    }
    if version >= 5:
        node["files"] = [
            {
                "path": name,
                "starting_time": {"nanoseconds_since_epoch": min(t for _, t, _ in keys)},
                "duration": {"nanoseconds": max(t for _, t, _ in keys) - min(t for _, t, _ in keys)},
                "message_count": len(keys),
            }
            for name, keys in files
        ]
    if version >= 6:
        node["custom_data"] = custom
    if version >= 8:
        node["ros_distro"] = "jazzy"
    return {"rosbag2_bagfile_information": node}


def rewrite(source: Path, target: Path, shape: Shape, version: int | None = 9) -> Path:
    """Writes ``source``'s messages into the folder ``target`` in ``shape``; returns the bag (folder or file).

    ``version`` None: no metadata.yaml, the one file itself is returned (a bare file).
    """
    items, custom = source_messages(source)
    target.mkdir(parents=True)
    size = -(-len(items) // shape.files)
    names = []
    for number in range(shape.files):
        part = items[number * size : (number + 1) * size]
        path = target / f"{target.name}_{number}.mcap"
        _write_mcap(path, part, shape)
        name = path.name + (".zstd" if shape.file_compression else "")
        names.append((name, [(c.topic, m.log_time, m.data) for c, _, m in part]))  # uncompressed
    if version is None:
        return target / names[0][0]
    types = {channel.topic: schema.name for channel, schema, _ in items}
    mode = "FILE" if shape.file_compression else "MESSAGE" if shape.message_compression else ""
    document = metadata_yaml(version, names, types, custom, mode)
    (target / "metadata.yaml").write_text(yaml.safe_dump(document, sort_keys=False))
    return target


def mcap_bytes(path: Path) -> bytes:
    """A storage file's MCAP bytes (decompressed if file-compressed)."""
    data = path.read_bytes()
    return zstandard.ZstdDecompressor().decompress(data) if path.name.endswith(".zstd") else data


def stream_messages(data: bytes, channels: dict[int, str] | None = None) -> list[Key]:
    """Messages of MCAP bytes read record by record until the end or the first error (StreamReader)."""
    channels = {} if channels is None else channels
    found: list[Key] = []
    try:
        for record in StreamReader(io.BytesIO(data), skip_magic=False, validate_crcs=True).records:
            if isinstance(record, Channel):
                channels.setdefault(record.id, record.topic)
            elif isinstance(record, Message) and record.channel_id in channels:
                found.append((channels[record.channel_id], record.log_time, bytes(record.data)))
    except Exception:
        pass
    return found


def bag_messages(bag: Path) -> list[Key]:
    """Every message of a bag's storage files (or of one bare file), read by :func:`stream_messages`."""
    paths = [bag] if bag.is_file() else sorted([*bag.glob("*.mcap"), *bag.glob("*.mcap.zstd")])
    return [key for path in paths for key in stream_messages(mcap_bytes(path))]
