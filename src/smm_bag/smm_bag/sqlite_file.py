"""One rosbag2 sqlite3 storage file (``.db3``, rosbag2's default before Iron) opened read-only.

What :class:`smm_bag.mcap_file.McapFile` offers the reader: channels (the ``topics`` rows), counts, time
span, ``rosbag2`` metadata records and messages, for rosbag2_storage_sqlite3's schemas 1 to 4. A message's
one stored time (its receive time) stands for its send time too.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import quote

from mcap.records import Channel, Metadata

from smm_bag.errors import CorruptBagError

__all__ = ["SqliteFile"]


class SqliteFile:
    """A ``.db3`` file's topics, counts and messages.

    Raises:
        CorruptBagError: Not an sqlite3 database, or without rosbag2's ``topics`` and ``messages`` tables.
    """

    def __init__(self, path: Path, name: Path | None = None) -> None:
        self.path = name if name is not None else path
        try:
            self._db = sqlite3.connect(f"file:{quote(str(path))}?mode=ro", uri=True)
        except sqlite3.Error as error:
            raise CorruptBagError(f"{self.path}: cannot open the sqlite3 file ({error})") from None
        try:
            self._load()
        except sqlite3.Error as error:
            self._db.close()
            raise CorruptBagError(f"{self.path}: not a readable rosbag2 sqlite3 file ({error})") from None
        except BaseException:
            self._db.close()
            raise

    def _load(self) -> None:
        tables = {row[0] for row in self._db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        if not {"topics", "messages"} <= tables:
            raise CorruptBagError(
                f"{self.path}: an sqlite3 file without rosbag2's topics and messages tables"
            )
        columns = {row[1] for row in self._db.execute("PRAGMA table_info(topics)")}
        qos = "offered_qos_profiles" if "offered_qos_profiles" in columns else "''"
        digest = "type_description_hash" if "type_description_hash" in columns else "''"
        self.channels: dict[int, Channel] = {}
        self._types: dict[int, str] = {}
        query = f"SELECT id, name, type, serialization_format, {qos}, {digest} FROM topics ORDER BY id"
        for key, topic, type_name, encoding, profiles, type_hash in self._db.execute(query):
            metadata = {"offered_qos_profiles": profiles or "", "topic_type_hash": type_hash or ""}
            self.channels[key] = Channel(
                id=key, schema_id=0, topic=topic, message_encoding=encoding, metadata=metadata
            )
            self._types[key] = type_name
        self.counts: dict[int, int] = {
            key: count
            for key, count in self._db.execute("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id")
        }
        first, last = self._db.execute("SELECT MIN(timestamp), MAX(timestamp) FROM messages").fetchone()
        self.span: tuple[int, int] | None = None if first is None else (int(first), int(last))
        """Earliest and latest message time (ns); None without messages."""
        self.metadata: list[Metadata] = []
        if "metadata" in tables:
            rows = self._db.execute("SELECT metadata FROM metadata ORDER BY id")
            self.metadata = [
                Metadata(name="rosbag2", metadata={"serialized_metadata": text}) for (text,) in rows if text
            ]
        self.ros_distro = ""
        if "schema" in tables and "ros_distro" in {
            row[1] for row in self._db.execute("PRAGMA table_info(schema)")
        }:
            row = self._db.execute("SELECT ros_distro FROM schema").fetchone()
            self.ros_distro = str(row[0] or "") if row else ""
        self._definitions: dict[str, tuple[str, str]] = {}
        if "message_definitions" in tables:
            for type_name, encoding, text in self._db.execute(
                "SELECT topic_type, encoding, encoded_message_definition FROM message_definitions"
            ):
                self._definitions[type_name] = (encoding or "", text or "")

    def type_name(self, channel: Channel) -> str:
        """The ``type`` of a channel's topic row (``pkg/msg/Type``)."""
        return self._types.get(channel.id, "")

    def definition(self, type_name: str) -> tuple[str, str] | None:
        """``(encoding, text)`` of a type's stored definition (schema 4 on; a service event: its srv's)."""
        found = self._definitions.get(type_name)
        if found is None and "/srv/" in type_name:
            found = self._definitions.get(type_name.removesuffix("_Event"))
        return found if found is not None and found[1] else None

    def messages(self, wanted: set[int] | None, ordered: bool) -> Iterator[tuple[int, int, int, bytes]]:
        """``(channel, time, time, data)`` of the channels ``wanted`` (all if None): stored order, or by time.

        Raises:
            CorruptBagError: The database cannot be read on.
        """
        keys = sorted(self.channels if wanted is None else wanted & set(self.channels))
        if not keys:
            return
        order = "timestamp, id" if ordered else "id"
        marks = ", ".join("?" * len(keys))
        query = f"SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({marks}) ORDER BY {order}"
        try:
            for key, stamp, data in self._db.execute(query, keys):
                yield key, stamp, stamp, bytes(data)
        except sqlite3.Error as error:
            raise CorruptBagError(f"{self.path}: reading messages failed ({error})") from None

    def close(self) -> None:
        """Closes the database."""
        self._db.close()
