"""``smm-bag convert``: a bag this package reads (sqlite3, any MCAP shape) written again as an MCAP bag.

Every topic (counts of zero included) keeps its name, type, serialization format, offered QoS and type
hash; every message its bytes (rosbag2's message compression undone), receive and send times, in time
order; the bag keeps its custom data (the run manifest, a recorder's loss report) and ROS distro. Each
type's definition is the one the source stores (sqlite3 schema 4 on, MCAP schemas), else the installed
one (:func:`smm_bag.msgdefs.message_definition`), else none, as rosbag2 stores an unknown type (encoding
and text empty, rosbag2_storage's ``MessageDefinition::empty_message_definition_for``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from smm_bag.errors import UnknownTypeError
from smm_bag.msgdefs import MessageDefinition, message_definition
from smm_bag.reader import BagReader
from smm_bag.writer import BagWriter, WriterOptions

__all__ = ["ConvertResult", "convert_bag"]


@dataclass(frozen=True)
class ConvertResult:
    """What a conversion wrote: storage read, messages and topics, the types stored without definition."""

    source_storage: str
    messages: int
    topics: int
    undefined_types: tuple[str, ...]


def _definition(reader: BagReader, type_name: str, type_hash: str) -> MessageDefinition:
    stored = reader.stored_definition(type_name)
    if stored is not None:
        return MessageDefinition(type_name, stored[0], stored[1], type_hash)
    try:
        known = message_definition(type_name)
    except UnknownTypeError:
        return MessageDefinition(type_name, "", "", type_hash)
    return MessageDefinition(type_name, known.encoding, known.text, type_hash or known.type_hash)


def convert_bag(
    source: Path,
    target: Path,
    *,
    compression: Literal["none", "zstd"] = "none",
    progress: Callable[[int, int], None] | None = None,
) -> ConvertResult:
    """Writes the bag ``source`` as the MCAP bag ``target`` (a new folder); ``progress(done, total)``.

    Raises:
        BagError: ``source`` cannot be read (see :class:`BagReader`).
        BagExistsError: ``target`` exists.
    """
    with BagReader(source) as reader:
        metadata = reader.metadata
        options = WriterOptions(
            compression=compression,
            custom_data=dict(metadata.custom_data),
            ros_distro=metadata.ros_distro,
            loss_report=False,
        )
        undefined: list[str] = []
        written = 0
        with BagWriter(target, options) as writer:
            for topic in metadata.topics:
                definition = _definition(reader, topic.type, topic.type_description_hash)
                if not definition.text and definition.type not in undefined:
                    undefined.append(definition.type)
                writer.create_topic(
                    topic.name,
                    topic.type,
                    topic.offered_qos_profiles,
                    topic.serialization_format,
                    definition=definition,
                )
            total = metadata.message_count
            report = None if progress is None else (lambda read: progress(read, total))
            for message in reader.messages(progress=report):
                writer.write(message.topic, message.data, message.log_time_ns, message.publish_time_ns)
                written += 1
    return ConvertResult(metadata.storage_identifier, written, len(metadata.topics), tuple(undefined))
