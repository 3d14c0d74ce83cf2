"""The committed sample bag's records, read with mcap's StreamReader (not the stack's reader)."""

from __future__ import annotations

import functools
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from bag.corpus.mcap_bytes import Message as Key
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

SAMPLE = Path(__file__).resolve().parents[3] / "bags" / "sample_case2_fpdeso"


@dataclass(frozen=True)
class Sample:
    """Every schema, channel and message of the sample (in file order) and its metadata.yaml."""

    schemas: tuple[Schema, ...]
    channels: tuple[Channel, ...]
    messages: tuple[Message, ...]
    metadata_records: tuple[Metadata, ...]
    document: dict[str, Any]

    @property
    def info(self) -> dict[str, Any]:
        info: dict[str, Any] = self.document["rosbag2_bagfile_information"]
        return info

    @property
    def custom_data(self) -> dict[str, str]:
        return dict(self.info.get("custom_data") or {})

    def topic(self, channel_id: int) -> str:
        return next(c.topic for c in self.channels if c.id == channel_id)

    def keys(self) -> list[Key]:
        topics = {c.id: c.topic for c in self.channels}
        return [Key(topics[m.channel_id], m.log_time, m.publish_time, bytes(m.data)) for m in self.messages]


@functools.cache
def sample() -> Sample:
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    messages: list[Message] = []
    metadata: list[Metadata] = []
    (path,) = sorted(SAMPLE.glob("*.mcap"))
    with path.open("rb") as stream:
        for record in StreamReader(stream, skip_magic=False, emit_chunks=False, validate_crcs=True).records:
            if isinstance(record, Schema):
                schemas.setdefault(record.id, record)
            elif isinstance(record, Channel):
                channels.setdefault(record.id, record)
            elif isinstance(record, Message):
                messages.append(record)
            elif isinstance(record, Metadata):
                metadata.append(record)
    document = yaml.safe_load((SAMPLE / "metadata.yaml").read_text())
    return Sample(
        tuple(schemas.values()), tuple(channels.values()), tuple(messages), tuple(metadata), document
    )


def file_messages(path: Path) -> list[Key]:
    """Every message of one undamaged MCAP file, by mcap's StreamReader iterating every record."""
    topics: dict[int, str] = {}
    found: list[Key] = []
    with path.open("rb") as stream:
        reader = StreamReader(stream, skip_magic=False, emit_chunks=False, validate_crcs=True)
        for record in reader.records:
            if isinstance(record, Channel):
                topics[record.id] = record.topic
            elif isinstance(record, Message):
                found.append(
                    Key(topics[record.channel_id], record.log_time, record.publish_time, record.data)
                )
    return found


def topic_counts(keys: list[Key]) -> Counter[str]:
    return Counter(key.topic for key in keys)
