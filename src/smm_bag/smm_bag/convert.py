"""``smm-bag convert``: a bag this package reads (sqlite3, any MCAP shape) written again as an MCAP bag.

Topics keep name, type, format, QoS and hash; messages their bytes and times; the bag its custom data and
distro. A type's definition is the one the source stores, else the installed one, else none (encoding and
text empty, as rosbag2 stores an unknown type). docs/BAGS.md, "smm-bag".
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
