"""Loss accounting of a recording: per topic messages received vs written, and gaps in the stamps."""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

__all__ = ["NEW_TIMELINE_NS", "LossAccounting", "TopicLoss"]

NEW_TIMELINE_NS = 60_000_000_000
"""A stamp this much (ns) before the latest starts a new timeline, gaps checked from it (docs/BAGS.md)."""


@dataclass
class TopicLoss:
    """Counters of one topic.

    Attributes:
        received: Messages handed to the recorder.
        written: Messages written to storage.
        gaps: Stamp steps longer than 1.5 periods (stamp-checked topics only).
        missing: Samples missing in those gaps (step / period - 1, rounded).
        out_of_order: Stamps not after the previous one.
        last_stamp_ns: Latest stamp seen (None before the first).
    """

    received: int = 0
    written: int = 0
    gaps: int = 0
    missing: int = 0
    out_of_order: int = 0
    last_stamp_ns: int | None = None

    @property
    def lost(self) -> int:
        """Received but not written."""
        return self.received - self.written

    def as_dict(self) -> dict[str, int]:
        """Counters for JSON and diagnostics."""
        return {
            "received": self.received,
            "written": self.written,
            "lost": self.lost,
            "stamp_gaps": self.gaps,
            "stamp_missing": self.missing,
            "stamp_out_of_order": self.out_of_order,
        }


@dataclass
class LossAccounting:
    """Counters of every topic; stamps checked on ``stamped_topics`` against ``period_ns``.

    Args:
        period_ns: Expected stamp period of the stamp-checked topics (ns), > 0.
        stamped_topics: Topics whose stamps are checked for gaps (the 1 kHz topics).
    """

    period_ns: int = 1_000_000
    stamped_topics: frozenset[str] = frozenset()
    topics: dict[str, TopicLoss] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.period_ns <= 0:
            raise ValueError(f"period_ns must be > 0, got {self.period_ns}")

    def _topic(self, topic: str) -> TopicLoss:
        entry = self.topics.get(topic)
        if entry is None:
            entry = self.topics[topic] = TopicLoss()
        return entry

    def received(self, topic: str, count: int = 1) -> None:
        """Counts messages handed to the recorder."""
        self._topic(topic).received += count

    def written(self, topic: str, stamp_ns: int | None = None) -> None:
        """Counts one written message and checks its stamp (if the topic is stamp-checked)."""
        entry = self._topic(topic)
        entry.written += 1
        if stamp_ns is None or topic not in self.stamped_topics:
            return
        last = entry.last_stamp_ns
        if last is not None and last - stamp_ns > NEW_TIMELINE_NS:
            last = None  # the run after the preflight's rehearsal (stamped an hour ahead): checked afresh
        entry.last_stamp_ns = stamp_ns if last is None else max(last, stamp_ns)
        if last is None:
            return
        step = stamp_ns - last
        if step <= 0:
            entry.out_of_order += 1
        elif 2 * step > 3 * self.period_ns:
            entry.gaps += 1
            entry.missing += max(round(step / self.period_ns) - 1, 1)

    @property
    def total_lost(self) -> int:
        """Received but not written, all topics."""
        return sum(entry.lost for entry in self.topics.values())

    @property
    def total_missing(self) -> int:
        """Samples missing in stamp gaps, all topics."""
        return sum(entry.missing for entry in self.topics.values())

    def as_dict(self) -> dict[str, dict[str, int]]:
        """Per-topic counters, sorted by topic."""
        return {topic: self.topics[topic].as_dict() for topic in sorted(self.topics)}

    def to_json(self) -> str:
        """The loss report stored in the bag's custom data (``smm.loss``)."""
        return json.dumps({"period_ns": self.period_ns, "topics": self.as_dict()}, sort_keys=True)

    def summary_lines(self, topics: Iterable[str] | None = None) -> list[str]:
        """One line per topic: received, written, lost, gaps."""
        chosen = sorted(self.topics) if topics is None else list(topics)
        lines = []
        for topic in chosen:
            entry = self.topics.get(topic, TopicLoss())
            gap = (
                f", {entry.gaps} stamp gaps ({entry.missing} samples)" if topic in self.stamped_topics else ""
            )
            lines.append(
                f"{topic}: received {entry.received}, written {entry.written}, lost {entry.lost}{gap}"
            )
        return lines


def loss_from_json(text: str) -> Mapping[str, Mapping[str, int]]:
    """Per-topic counters from a ``smm.loss`` custom-data value."""
    document = json.loads(text)
    topics = document.get("topics", {}) if isinstance(document, dict) else {}
    return {str(topic): dict(values) for topic, values in topics.items()}
