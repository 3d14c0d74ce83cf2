"""A node's health, pure: levels, the worst finding, and counts per diagnostics period."""

from __future__ import annotations

import enum
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

__all__ = ["CountWindows", "Health", "Level", "level_for", "worst"]


class Level(enum.IntEnum):
    """``DiagnosticStatus`` levels."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True)
class Health:
    """A node's health at one instant.

    Attributes:
        level: Worst level of the node's checks.
        message: One line saying why (the worst finding first).
        values: Figures shown beside it (rates, counters, last error); formatted with ``str``.
    """

    level: Level
    message: str
    values: Mapping[str, object] = field(default_factory=dict)


def level_for(value: float, warn: float, error: float) -> Level:
    """OK below ``warn``, WARN from ``warn``, ERROR from ``error`` (thresholds inclusive)."""
    if value >= error:
        return Level.ERROR
    if value >= warn:
        return Level.WARN
    return Level.OK


def worst(findings: list[tuple[Level, str]], fine: str, values: Mapping[str, object]) -> Health:
    """The :class:`Health` of ``findings`` ``(level, text)``: worst level, worst text first; else ``fine``."""
    ordered = sorted(findings, key=lambda finding: -int(finding[0]))
    if not ordered:
        return Health(Level.OK, fine, values)
    return Health(ordered[0][0], "; ".join(text for _, text in ordered), values)


class CountWindows:
    """Counts per diagnostics period: the increase over the last complete period; the current one's start."""

    def __init__(self, counts: Mapping[str, int]) -> None:
        self.start = dict(counts)
        self.last: dict[str, int] = {}
        self.started = time.monotonic()
        self.duration = 0.0

    def since(self, counts: Mapping[str, int]) -> dict[str, int]:
        """Increase of each count since the current period started."""
        return {name: count - self.start.get(name, 0) for name, count in counts.items()}

    def roll(self, counts: Mapping[str, int]) -> None:
        """End the current period at ``counts``."""
        now = time.monotonic()
        self.last = self.since(counts)
        self.start = dict(counts)
        self.duration = now - self.started
        self.started = now

    def rate(self, name: str) -> float:
        """Rate of ``name`` over the last complete period (1/s), 0 before the first."""
        return self.last.get(name, 0) / self.duration if self.duration > 0.0 else 0.0
