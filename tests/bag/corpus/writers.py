"""The sample's messages re-written by writers this stack does not own: rosbags, mcap (Python), @mcap/core
(node), and a generator of the MCAP conformance suite's shapes (this module's own record encoder).

Each function writes a new bag (a folder, or a bare ``.mcap`` file) at ``path`` and returns what
``smm-bag`` is given.
"""

from __future__ import annotations

import copy
import json
import shutil
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
import zstandard
from bag.corpus import mcap_bytes as mb
from bag.corpus.sample import Sample, sample
from mcap.records import Message
from mcap.writer import CompressionType, IndexType, Writer
from rosbags.rosbag2 import Writer as RosbagsWriter
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.metadata import parse_qos

JS_DIR = Path(__file__).resolve().parent / "js"

# rmw's enum values, as metadata versions <= 8 store them (rmw/types.h; rosbag2_storage qos.cpp).
_HISTORY = {"system_default": 0, "keep_last": 1, "keep_all": 2, "unknown": 3}
_RELIABILITY = {"system_default": 0, "reliable": 1, "best_effort": 2, "unknown": 3, "best_available": 4}
_DURABILITY = {"system_default": 0, "transient_local": 1, "volatile": 2, "unknown": 3, "best_available": 4}
_LIVELINESS = {
    "system_default": 0,
    "automatic": 1,
    "manual_by_node": 2,
    "manual_by_topic": 3,
    "unknown": 4,
    "best_available": 5,
}


def _topics(source: Sample) -> list[dict[str, Any]]:
    return [entry["topic_metadata"] for entry in source.info["topics_with_message_count"]]


# ---------------------------------------------------------------------------------------------- rosbags


def rosbags_bag(
    path: Path,
    *,
    version: int = 9,
    compression: str = "none",
    files: int = 1,
    manifest: bool = True,
    storage: StoragePlugin = StoragePlugin.MCAP,
) -> Path:
    """rosbags' rosbag2 writer (MCAP storage); versions 4-7 are its version 8 bag with metadata.yaml
    rewritten as rosbag2 writes that version; ``compression``: none, storage (zstd chunks), file, message;
    ``files`` > 1: one rosbags bag per time slice, joined into one folder."""
    source = sample()
    path.mkdir(parents=True)
    messages = source.messages
    bounds = [len(messages) * k // files for k in range(files + 1)]
    documents = []
    for index in range(files):
        part = path.parent / f".{path.name}.part{index}"
        shutil.rmtree(part, ignore_errors=True)
        writer = RosbagsWriter(part, version=9 if version >= 9 else 8, storage_plugin=storage)
        if compression != "none":
            writer.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
        if manifest:
            for key, value in source.custom_data.items():
                writer.set_custom_data(key, value)
        writer.open()
        connections = dict(_connection(writer, source, topic["name"]) for topic in _topics(source))
        for message in messages[bounds[index] : bounds[index + 1]]:
            writer.write(connections[message.channel_id], message.log_time, message.data)
        writer.close()
        document = yaml.safe_load((part / "metadata.yaml").read_text())
        (produced,) = document["rosbag2_bagfile_information"]["relative_file_paths"]
        name = f"{path.name}_{index}" + produced[len(part.name) :]
        (part / produced).rename(path / name)
        shutil.rmtree(part)
        documents.append((name, document))
    info = _join(documents)
    (path / "metadata.yaml").write_text(
        yaml.safe_dump({"rosbag2_bagfile_information": as_version(info, version)})
    )
    return path


def _connection(writer: RosbagsWriter, source: Sample, name: str) -> tuple[int, Any]:
    """(sample channel id, rosbags connection) of the sample's topic ``name``, as its metadata.yaml has it."""
    topic = next(t for t in _topics(source) if t["name"] == name)
    channel = next(c for c in source.channels if c.topic == name)
    schema = next(s for s in source.schemas if s.id == channel.schema_id)
    connection = writer.add_connection(
        name,
        topic["type"],
        msgdef=schema.data.decode(),
        rihs01=topic["type_description_hash"],
        offered_qos_profiles=parse_qos(topic["offered_qos_profiles"]),
    )
    return channel.id, connection


def _join(documents: list[tuple[str, dict[str, Any]]]) -> dict[str, Any]:
    """One metadata of several single-file ones (counts added, files listed in order)."""
    first = copy.deepcopy(documents[0][1]["rosbag2_bagfile_information"])
    infos = [document["rosbag2_bagfile_information"] for _, document in documents]
    start = min(i["starting_time"]["nanoseconds_since_epoch"] for i in infos)
    end = max(i["starting_time"]["nanoseconds_since_epoch"] + i["duration"]["nanoseconds"] for i in infos)
    first["starting_time"] = {"nanoseconds_since_epoch": start}
    first["duration"] = {"nanoseconds": end - start}
    first["message_count"] = sum(i["message_count"] for i in infos)
    first["relative_file_paths"] = [name for name, _ in documents]
    first["files"] = [{**i["files"][0], "path": name} for (name, _), i in zip(documents, infos, strict=True)]
    counts: dict[str, int] = {}
    for info in infos:
        for topic in info["topics_with_message_count"]:
            name = topic["topic_metadata"]["name"]
            counts[name] = counts.get(name, 0) + topic["message_count"]
    for topic in first["topics_with_message_count"]:
        topic["message_count"] = counts[topic["topic_metadata"]["name"]]
    return first


def _qos_v8(profiles: Any) -> str:
    """Version 4-8's ``offered_qos_profiles``: a YAML string of policies as rmw's integers."""
    if isinstance(profiles, str):
        return profiles
    converted = [
        {
            **profile,
            "history": _HISTORY[profile["history"]],
            "reliability": _RELIABILITY[profile["reliability"]],
            "durability": _DURABILITY[profile["durability"]],
            "liveliness": _LIVELINESS[profile["liveliness"]],
        }
        for profile in profiles
    ]
    return yaml.safe_dump(converted, sort_keys=False).strip() if converted else ""


def as_version(info: Mapping[str, Any], version: int) -> dict[str, Any]:
    """Metadata as rosbag2's yaml.hpp writes ``version`` (4-9): fields of later versions left out, QoS as a
    YAML string of integers below 9."""
    result = copy.deepcopy(dict(info))
    result["version"] = version
    for topic in result["topics_with_message_count"]:
        metadata = topic["topic_metadata"]
        if version < 9:
            metadata["offered_qos_profiles"] = _qos_v8(metadata["offered_qos_profiles"])
        if version < 7:
            metadata.pop("type_description_hash", None)
    if version < 8:
        result.pop("ros_distro", None)
    if version < 6:
        result.pop("custom_data", None)
    if version < 5:
        result.pop("files", None)
    return result


# ----------------------------------------------------------------------------------------- mcap (Python)


@dataclass(frozen=True)
class McapOptions:
    """The Python ``mcap`` Writer's options that change a file's shape."""

    chunked: bool = True
    chunk_size: int = 1024 * 1024
    compression: str = "zstd"
    crcs: bool = True
    data_crc: bool = False
    summary: bool = True
    """The whole summary; ``indexes``, ``repeat``, ``statistics``, ``offsets`` leave out one part."""
    indexes: bool = True
    repeat: bool = True
    statistics: bool = True
    offsets: bool = True
    manifest: bool = False
    extra_topic: tuple[str, str] | None = None
    """(topic, type) of an extra topic, one message per 100 of the sample's."""


NOT_INSTALLED = ("/corpus/not_installed", "smm_corpus_msgs/msg/NotInstalled")
"""A topic whose type no installed package defines (what ``ros2 bag play`` skips with a warning)."""


SERVICE_EVENTS = ("/corpus/add_two_ints/_service_event", "example_interfaces/srv/AddTwoInts_Event")
"""A service's event topic as rosbag2 Jazzy records it (``ros2 bag info`` lists it as a service)."""


def mcap_file(path: Path, options: McapOptions, source: Sample | None = None) -> Path:
    """A bare ``.mcap`` file of the sample's messages by mcap's Writer (the manifest, when kept, in the
    ``rosbag2`` metadata records exactly as the stack wrote them)."""
    source = source or sample()
    path.parent.mkdir(parents=True, exist_ok=True)
    summary = options.summary
    with path.open("wb") as stream:
        writer = Writer(
            stream,
            chunk_size=options.chunk_size,
            compression=CompressionType[options.compression.upper()],
            index_types=IndexType.ALL if summary and options.indexes else IndexType.NONE,
            repeat_channels=summary and options.repeat,
            repeat_schemas=summary and options.repeat,
            use_chunking=options.chunked,
            use_statistics=summary and options.statistics,
            use_summary_offsets=summary and options.offsets,
            enable_crcs=options.crcs,
            enable_data_crcs=options.data_crc,
        )
        writer.start(profile="ros2", library="mcap-python (smm corpus)")
        schema_ids = {s.id: writer.register_schema(s.name, s.encoding, s.data) for s in source.schemas}
        channel_ids = {
            c.id: writer.register_channel(c.topic, c.message_encoding, schema_ids[c.schema_id], c.metadata)
            for c in source.channels
        }
        if options.manifest:
            writer.add_metadata(source.metadata_records[0].name, source.metadata_records[0].metadata)
        if options.extra_topic:
            topic, kind = options.extra_topic
            extra = writer.register_channel(
                topic, "cdr", writer.register_schema(kind, "ros2msg", b"float64 x\n"), {}
            )
        for index, m in enumerate(source.messages):
            writer.add_message(channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence)
            if options.extra_topic and index % 100 == 0:
                payload = b"\x00\x01\x00\x00" + index.to_bytes(8, "little")
                writer.add_message(extra, m.log_time, payload, m.log_time, index)
        if options.manifest:
            writer.add_metadata(source.metadata_records[-1].name, source.metadata_records[-1].metadata)
        writer.finish()
    return path


def in_folder(file: Path, *, version: int = 9, source: Sample | None = None) -> Path:
    """Puts a single-file bag into a folder ``file.stem`` with a metadata.yaml of ``version``."""
    source = source or sample()
    folder = file.parent / file.name.split(".")[0]
    folder.mkdir()
    name = f"{folder.name}_0{''.join(file.suffixes)}"
    file.rename(folder / name)
    info = copy.deepcopy(source.info)
    info["relative_file_paths"] = [name]
    info["files"][0]["path"] = name
    (folder / "metadata.yaml").write_text(
        yaml.safe_dump({"rosbag2_bagfile_information": as_version(info, version)})
    )
    return folder


# ------------------------------------------------------------------------------------ @mcap/core (node)


def plain_mcap(source: Sample) -> bytes:
    """The sample as one unchunked MCAP without summary (this module's encoder): the node writer's input."""
    out = [mb.MAGIC, mb.record(mb.HEADER, mb.header("ros2", "smm corpus"))]
    out += [mb.record(mb.SCHEMA, mb.schema(s.id, s.name, s.encoding, s.data)) for s in source.schemas]
    out += [
        mb.record(mb.CHANNEL, mb.channel(c.id, c.schema_id, c.topic, c.message_encoding, c.metadata))
        for c in source.channels
    ]
    out.append(
        mb.record(
            mb.METADATA, mb.metadata(source.metadata_records[0].name, source.metadata_records[0].metadata)
        )
    )
    out += [
        mb.record(mb.MESSAGE, mb.message(m.channel_id, m.sequence, m.log_time, m.publish_time, m.data))
        for m in source.messages
    ]
    out += [mb.record(mb.DATA_END, b"\0\0\0\0"), mb.record(mb.FOOTER, bytes(20)), mb.MAGIC]
    return b"".join(out)


def js_file(path: Path, options: Mapping[str, Any]) -> Path:
    """@mcap/core's McapWriter (node) re-writing the sample with ``options`` (its options, compression)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    source = path.parent / f".{path.name}.input.mcap"
    source.write_bytes(plain_mcap(sample()))
    subprocess.run(
        ["node", str(JS_DIR / "write.mjs"), str(source), str(path), json.dumps(dict(options))],
        check=True,
        capture_output=True,
        timeout=300,
    )
    source.unlink()
    return path


# ------------------------------------------------------------------------------ conformance-suite shapes

SCHEMALESS = 99
"""Channel id of the schemaless channel of the ``schemaless`` shape."""

SHAPE_FEATURES = ("ch", "mx", "chx", "st", "sum", "rch", "rsh", "pad", "crc0")
"""The conformance suite's features (foxglove/mcap tests/conformance/variants/types.ts: chunks, message
index, chunk index, statistics, summary offsets, repeated channels, repeated schemas, padded records), and
CRCs of 0."""


def shapes() -> list[frozenset[str]]:
    """Every feature set the conformance suite would generate for a file with schemas and channels."""
    combos: list[frozenset[str]] = [frozenset()]
    for feature in SHAPE_FEATURES:
        combos += [c | {feature} for c in combos]
    valid = []
    for c in combos:
        if ("mx" in c or "chx" in c) and "ch" not in c:
            continue
        if "sum" in c and not c & {"chx", "rsh", "rch", "st"}:
            continue
        valid.append(c)
    return valid


def shape_name(features: frozenset[str]) -> str:
    return "-".join(["shape", *sorted(features)]) if features else "shape-plain"


def shape_file(
    path: Path, features: frozenset[str], *, chunk_messages: int = 700, topics_of: str = "smm"
) -> Path:
    """The sample (or, ``topics_of="other"``, its messages on topics that are not the stack's) in the
    shape ``features`` names, by this module's encoder."""
    source = sample()
    pad = 3 if "pad" in features else 0
    inner_pad = 3 if "inner-pad" in features else 0  # the suite pads top-level records only
    crc0 = "crc0" in features
    rename = (lambda t: t) if topics_of == "smm" else (lambda t: "/other" + t)
    out = bytearray(mb.MAGIC)

    def put(opcode: int, content: bytes) -> int:
        offset = len(out)
        out.extend(mb.record(opcode, content, pad))
        return offset

    put(mb.HEADER, mb.header("ros2", "smm corpus shapes"))
    schemas = [mb.schema(s.id, s.name, s.encoding, s.data) for s in source.schemas]
    channels = [
        mb.channel(c.id, c.schema_id, rename(c.topic), c.message_encoding, c.metadata)
        for c in source.channels
    ]
    messages: Sequence[Message] = source.messages
    if "schemaless" in features:  # a channel without schema (schema id 0), as the MCAP specification allows
        channels.append(mb.channel(SCHEMALESS, 0, "/corpus/schemaless", "json", {}))
        messages = [
            extra
            for k, m in enumerate(source.messages)
            for extra in (m, Message(SCHEMALESS, m.log_time, b'{"k": %d}' % k, m.log_time, k))[
                : 1 + (k % 100 == 0)
            ]
        ]
    chunk_indexes: list[bytes] = []
    stats_counts: dict[int, int] = {}
    if "ch" not in features:
        for content in schemas:
            put(mb.SCHEMA, content)
        for content in channels:
            put(mb.CHANNEL, content)
        for m in messages:
            put(mb.MESSAGE, mb.message(m.channel_id, m.sequence, m.log_time, m.publish_time, m.data))
    else:
        for first in range(0, len(messages), chunk_messages):
            group = messages[first : first + chunk_messages]
            inner = bytearray()
            index: dict[int, list[tuple[int, int]]] = {}
            if first == 0:
                for content in schemas:
                    inner += mb.record(mb.SCHEMA, content, inner_pad)
                for content in channels:
                    inner += mb.record(mb.CHANNEL, content, inner_pad)
            for m in group:
                index.setdefault(m.channel_id, []).append((m.log_time, len(inner)))
                inner += mb.record(
                    mb.MESSAGE,
                    mb.message(m.channel_id, m.sequence, m.log_time, m.publish_time, m.data),
                    inner_pad,
                )
            start, end = min(m.log_time for m in group), max(m.log_time for m in group)
            crc = 0 if crc0 else mb.zlib.crc32(inner)
            body = (
                mb.struct.pack("<QQQI", start, end, len(inner), crc)
                + mb.string("")
                + mb.struct.pack("<Q", len(inner))
                + bytes(inner)
            )
            chunk_offset = put(mb.CHUNK, body)
            chunk_length = len(out) - chunk_offset
            index_offsets: dict[int, int] = {}
            index_start = len(out)
            if "mx" in features:
                for channel_id, entries in sorted(index.items()):
                    array = b"".join(mb.struct.pack("<QQ", t, o) for t, o in entries)
                    index_offsets[channel_id] = put(
                        mb.MESSAGE_INDEX, mb.struct.pack("<HI", channel_id, len(array)) + array
                    )
            offsets_map = b"".join(mb.struct.pack("<HQ", k, v) for k, v in sorted(index_offsets.items()))
            chunk_indexes.append(
                mb.struct.pack("<QQQQ", start, end, chunk_offset, chunk_length)
                + mb.struct.pack("<I", len(offsets_map))
                + offsets_map
                + mb.struct.pack("<Q", len(out) - index_start)
                + mb.string("")
                + mb.struct.pack("<QQ", len(inner), len(inner))
            )
    for m in messages:
        stats_counts[m.channel_id] = stats_counts.get(m.channel_id, 0) + 1
    put(mb.DATA_END, mb.struct.pack("<I", 0 if crc0 else mb.zlib.crc32(out)))
    summary_start = len(out)
    groups: list[tuple[int, int, int]] = []

    def group(opcode: int, contents: list[bytes]) -> None:
        if contents:
            start = len(out)
            for content in contents:
                put(opcode, content)
            groups.append((opcode, start, len(out) - start))

    if "rsh" in features:
        group(mb.SCHEMA, schemas)
    if "rch" in features:
        group(mb.CHANNEL, channels)
    if "st" in features:
        counts = b"".join(mb.struct.pack("<HQ", k, v) for k, v in sorted(stats_counts.items()))
        chunk_count = len(chunk_indexes) if "ch" in features else 0
        group(
            mb.STATISTICS,
            [
                mb.struct.pack(
                    "<QHIIIIQQ",
                    len(messages),
                    len(schemas),
                    len(channels),
                    0,
                    0,
                    chunk_count,
                    min(m.log_time for m in messages),
                    max(m.log_time for m in messages),
                )
                + mb.struct.pack("<I", len(counts))
                + counts
            ],
        )
    if "chx" in features:
        group(mb.CHUNK_INDEX, chunk_indexes)
    offset_start = len(out)
    if "sum" in features:
        for opcode, start, length in groups:
            put(mb.SUMMARY_OFFSET, mb.struct.pack("<BQQ", opcode, start, length))
    if len(out) == summary_start:
        summary_start = offset_start = 0
    elif offset_start == len(out):
        offset_start = 0
    footer_prefix = mb.struct.pack("<BQQQ", mb.FOOTER, 20, summary_start, offset_start)  # never padded
    covered = bytes(out[summary_start:]) + footer_prefix if summary_start else b""
    summary_crc = 0 if crc0 or not summary_start else mb.zlib.crc32(covered)
    out += footer_prefix + mb.struct.pack("<I", summary_crc) + mb.MAGIC
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(bytes(out))
    return path


# -------------------------------------------------------------------------------------- file compression


def zstd_file(path: Path) -> Path:
    """rosbag2's file compression: the whole file as one zstd frame, ``.mcap.zstd`` (the original removed)."""
    target = path.with_name(path.name + ".zstd")
    target.write_bytes(zstandard.ZstdCompressor().compress(path.read_bytes()))
    path.unlink()
    return target


def not_installed_bag(path: Path, count: int = 200, storage: StoragePlugin = StoragePlugin.MCAP) -> Path:
    """rosbags' writer: the sample's first ``count`` joint states and a topic of a type not installed."""
    source = sample()
    writer = RosbagsWriter(path, version=9, storage_plugin=storage)
    writer.open()
    channel_id, states = _connection(writer, source, "/smm/joint_states")
    other = writer.add_connection(*NOT_INSTALLED, msgdef="float64 x\n", rihs01="RIHS01_" + "0" * 64)
    written = 0
    for message in source.messages:
        if message.channel_id == channel_id and written < count:
            writer.write(states, message.log_time, message.data)
            if written % 4 == 0:
                writer.write(other, message.log_time, b"\x00\x01\x00\x00" + bytes(8))
            written += 1
    writer.close()
    return path
