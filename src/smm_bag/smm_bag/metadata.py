"""``metadata.yaml`` of a rosbag2 folder, versions 4 to 9 as rosbag2 Jazzy reads and writes them (yaml.hpp).

Versions <= 8 hold each topic's offered QoS profiles as one YAML string with enum integers, version 9 as a
YAML list with policy names; a file is written back in the version it was read in.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import yaml

from smm_bag.errors import CorruptBagError, NotABagError, OtherStorageError
from smm_bag.qos import QosProfile, dump_profiles, load_profiles

__all__ = [
    "METADATA_FILE",
    "METADATA_VERSION",
    "NO_START_NS",
    "READABLE_STORAGE",
    "BagMetadata",
    "FileInfo",
    "TopicInfo",
    "read_metadata",
    "recorded_metadata",
    "service_event",
    "topic_from_channel",
    "write_metadata",
]

METADATA_FILE = "metadata.yaml"
READABLE_STORAGE = ("mcap", "sqlite3")
"""``storage_identifier``s this package reads."""
METADATA_VERSION = 9
OLDEST_VERSION = 4
"""The oldest metadata version read (the first with offered QoS profiles; rosbag2 Jazzy reads it)."""
NO_START_NS = 9_223_372_036_854_775_807
"""``starting_time`` rosbag2 writes before the first message (nanoseconds::max())."""


_EVENT_TOPIC = "/_service_event"
_EVENT_TYPE = "_Event"


def service_event(name: str, type_name: str) -> tuple[str, str] | None:
    """``(service, service type)`` of a service-event topic (rosbag2_cpp service_utils), else None."""
    if len(name) <= len(_EVENT_TOPIC) or not name.endswith(_EVENT_TOPIC):
        return None
    if len(type_name) <= len(_EVENT_TYPE) or "/srv/" not in type_name or not type_name.endswith(_EVENT_TYPE):
        return None
    return name[: -len(_EVENT_TOPIC)], type_name[: -len(_EVENT_TYPE)]


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag: name, type, serialization format, offered QoS, type hash, message count."""

    name: str
    type: str
    serialization_format: str = "cdr"
    offered_qos_profiles: tuple[QosProfile, ...] = ()
    type_description_hash: str = ""
    message_count: int = 0

    def to_yaml_node(self, version: int = METADATA_VERSION) -> dict[str, Any]:
        """``topics_with_message_count`` entry, QoS encoded as metadata ``version`` holds it."""
        profiles: Any = (
            [profile.to_yaml_node(version) for profile in self.offered_qos_profiles]
            if version >= 9
            else dump_profiles(self.offered_qos_profiles, version)
        )
        return {
            "topic_metadata": {
                "name": self.name,
                "type": self.type,
                "serialization_format": self.serialization_format,
                "offered_qos_profiles": profiles,
                "type_description_hash": self.type_description_hash,
            },
            "message_count": self.message_count,
        }


@dataclass(frozen=True)
class FileInfo:
    """One storage file: relative path, first message time (ns), duration (ns), message count."""

    path: str
    starting_time_ns: int = NO_START_NS
    duration_ns: int = 0
    message_count: int = 0

    def to_yaml_node(self) -> dict[str, Any]:
        """``files`` entry."""
        return {
            "path": self.path,
            "starting_time": {"nanoseconds_since_epoch": self.starting_time_ns},
            "duration": {"nanoseconds": self.duration_ns},
            "message_count": self.message_count,
        }


@dataclass(frozen=True)
class BagMetadata:
    """The content of ``metadata.yaml`` (times in integer ns)."""

    topics: tuple[TopicInfo, ...] = ()
    files: tuple[FileInfo, ...] = ()
    starting_time_ns: int = NO_START_NS
    duration_ns: int = 0
    message_count: int = 0
    custom_data: Mapping[str, str] = field(default_factory=dict)
    ros_distro: str = "jazzy"
    storage_identifier: str = "mcap"
    compression_format: str = ""
    compression_mode: str = ""
    version: int = METADATA_VERSION

    @property
    def relative_file_paths(self) -> tuple[str, ...]:
        """Storage files, in order."""
        return tuple(info.path for info in self.files)

    def topic(self, name: str) -> TopicInfo | None:
        """The topic called ``name``, or None."""
        return next((topic for topic in self.topics if topic.name == name), None)

    def to_yaml_node(self) -> dict[str, Any]:
        """The mapping under ``rosbag2_bagfile_information`` (also the MCAP ``rosbag2`` metadata record)."""
        return {
            "version": self.version,
            "storage_identifier": self.storage_identifier,
            "duration": {"nanoseconds": self.duration_ns},
            "starting_time": {"nanoseconds_since_epoch": self.starting_time_ns},
            "message_count": self.message_count,
            "topics_with_message_count": [topic.to_yaml_node(self.version) for topic in self.topics],
            "compression_format": self.compression_format,
            "compression_mode": self.compression_mode,
            "relative_file_paths": list(self.relative_file_paths),
            "files": [info.to_yaml_node() for info in self.files],
            "custom_data": dict(self.custom_data),
            "ros_distro": self.ros_distro,
        }

    def serialized(self) -> str:
        """YAML text of :meth:`to_yaml_node` (the ``serialized_metadata`` of the MCAP record)."""
        return str(yaml.safe_dump(self.to_yaml_node(), sort_keys=False, default_flow_style=False))

    def with_counts(self, topics: tuple[TopicInfo, ...], files: tuple[FileInfo, ...]) -> BagMetadata:
        """A copy with new topics and files; totals, start and duration recomputed from the files."""
        started = [info for info in files if info.message_count > 0]
        start = min((info.starting_time_ns for info in started), default=NO_START_NS)
        end = max((info.starting_time_ns + info.duration_ns for info in started), default=start)
        return replace(
            self,
            topics=topics,
            files=files,
            starting_time_ns=start,
            duration_ns=end - start if started else 0,
            message_count=sum(topic.message_count for topic in topics),
        )


def topic_from_channel(name: str, type_name: str, encoding: str, metadata: Mapping[str, str]) -> TopicInfo:
    """A topic's entry from an MCAP channel (QoS and type hash as rosbag2's MCAP plugin stores them)."""
    try:
        profiles = tuple(load_profiles(metadata.get("offered_qos_profiles")))
    except CorruptBagError:
        profiles = ()
    return TopicInfo(name, type_name, encoding, profiles, metadata.get("topic_type_hash", ""))


def recorded_metadata(records: Sequence[tuple[str, Mapping[str, str]]]) -> BagMetadata | None:
    """The last ``rosbag2`` metadata record (name, fields) that parses (rosbag2 writes one into each file)."""
    for name, fields in reversed(records):
        text = fields.get("serialized_metadata") if name == "rosbag2" else None
        if text:
            try:
                return parse_metadata(yaml.safe_load(text), "rosbag2 metadata record")
            except (CorruptBagError, yaml.YAMLError):
                continue
    return None


def write_metadata(directory: Path, metadata: BagMetadata) -> None:
    """Writes ``metadata.yaml`` atomically (temporary file, fsync, rename)."""
    target = directory / METADATA_FILE
    temporary = directory / f".{METADATA_FILE}.tmp"
    text = yaml.safe_dump(
        {"rosbag2_bagfile_information": metadata.to_yaml_node()}, sort_keys=False, default_flow_style=False
    )
    with temporary.open("w", encoding="utf-8") as stream:
        stream.write(text)
        stream.flush()
        os.fsync(stream.fileno())
    temporary.replace(target)


def _int(node: Mapping[str, Any], *keys: str) -> int:
    value: Any = node
    for key in keys:
        if not isinstance(value, Mapping) or key not in value:
            raise CorruptBagError(f"metadata.yaml: missing {'.'.join(keys)}")
        value = value[key]
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise CorruptBagError(f"metadata.yaml: {'.'.join(keys)} must be an integer >= 0, got {value!r}")
    return value


def parse_metadata(node: Any, source: str = METADATA_FILE) -> BagMetadata:
    """Parses the mapping under ``rosbag2_bagfile_information`` (versions 4 to 9).

    Raises:
        CorruptBagError: A field is missing or of the wrong kind.
    """
    if not isinstance(node, Mapping):
        raise CorruptBagError(f"{source}: rosbag2_bagfile_information must be a mapping")
    version = _int(node, "version")
    if not OLDEST_VERSION <= version <= METADATA_VERSION:
        raise CorruptBagError(
            f"{source}: metadata version {version} not supported ({OLDEST_VERSION} to {METADATA_VERSION})"
        )
    try:
        topics = []
        for entry in node.get("topics_with_message_count") or []:
            meta = entry["topic_metadata"]
            topics.append(
                TopicInfo(
                    name=str(meta["name"]),
                    type=str(meta["type"]),
                    serialization_format=str(meta["serialization_format"]),
                    offered_qos_profiles=tuple(load_profiles(meta.get("offered_qos_profiles"))),
                    type_description_hash=str(meta.get("type_description_hash", "")),
                    message_count=_int(entry, "message_count"),
                )
            )
        files = tuple(
            FileInfo(
                path=str(entry["path"]),
                starting_time_ns=_int(entry, "starting_time", "nanoseconds_since_epoch"),
                duration_ns=_int(entry, "duration", "nanoseconds"),
                message_count=_int(entry, "message_count"),
            )
            for entry in node.get("files") or []
        )
        paths = [str(path) for path in node.get("relative_file_paths") or []]
        if not files:
            files = tuple(FileInfo(path=path) for path in paths)
        custom = node.get("custom_data") or {}
        if not isinstance(custom, Mapping):
            raise CorruptBagError(f"{source}: custom_data must be a mapping")
        return BagMetadata(
            topics=tuple(topics),
            files=files,
            starting_time_ns=_int(node, "starting_time", "nanoseconds_since_epoch"),
            duration_ns=_int(node, "duration", "nanoseconds"),
            message_count=_int(node, "message_count"),
            custom_data={str(key): str(value) for key, value in custom.items()},
            ros_distro=str(node.get("ros_distro", "")),
            storage_identifier=str(node["storage_identifier"]),
            compression_format=str(node.get("compression_format", "")),
            compression_mode=str(node.get("compression_mode", "")),
            version=version,
        )
    except (KeyError, TypeError, AttributeError) as error:
        raise CorruptBagError(f"{source}: malformed entry ({error!r})") from None


def read_metadata(directory: Path) -> BagMetadata:
    """Reads ``directory/metadata.yaml``.

    Raises:
        NotABagError: No directory or no ``metadata.yaml``.
        OtherStorageError: The bag's storage is neither MCAP nor sqlite3.
        CorruptBagError: The file is not valid rosbag2 metadata.
    """
    if not directory.is_dir():
        raise NotABagError(f"{directory} is not a directory (a rosbag2 bag is a folder with metadata.yaml)")
    path = directory / METADATA_FILE
    if not path.is_file():
        raise NotABagError(f"{directory} is not a rosbag2 bag: it has no {METADATA_FILE}")
    try:
        document = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        raise CorruptBagError(f"{path} is not valid YAML: {error}") from None
    if not isinstance(document, Mapping) or "rosbag2_bagfile_information" not in document:
        raise CorruptBagError(f"{path} has no rosbag2_bagfile_information")
    node = document["rosbag2_bagfile_information"]
    storage = node.get("storage_identifier", "mcap") if isinstance(node, Mapping) else "mcap"
    if storage not in READABLE_STORAGE:
        raise OtherStorageError(f"{directory}: {storage} storage (smm-bag reads MCAP and sqlite3 bags)")
    return parse_metadata(document["rosbag2_bagfile_information"], str(path))
