"""A time window of a run (``--start`` / ``--end``), shared by ``analyze``, ``rerun`` and ``identify``.

A bound is seconds from the run's first complete step (``12.5``) or bag time, the stamp in seconds after
``@`` (``@1700000012.5``); both are read as exact decimals and rounded to the nanosecond. The window keeps the
steps with start <= stamp < end, so adjacent windows tile a run (docs/BAGS.md, "Windows and segments").
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation

__all__ = ["TimeBound", "TimeWindow", "add_reading_options", "parse_bound", "window_from_options"]

_NS = 1_000_000_000


@dataclass(frozen=True)
class TimeBound:
    """One end of a window: ``ns`` after the run's first step (relative) or a bag stamp (absolute)."""

    ns: int
    absolute: bool

    def resolve(self, first_ns: int) -> int:
        """The bound as a bag stamp (ns), given the run's first step."""
        return self.ns if self.absolute else first_ns + self.ns

    def __str__(self) -> str:
        text = f"{Decimal(self.ns) / _NS:f}"
        return f"@{text}" if self.absolute else text


@dataclass(frozen=True)
class TimeWindow:
    """Steps with ``start <= stamp < end``; a missing bound is open."""

    start: TimeBound | None = None
    end: TimeBound | None = None

    @property
    def whole(self) -> bool:
        """True when neither bound is set."""
        return self.start is None and self.end is None

    def resolve(self, first_ns: int) -> tuple[int | None, int | None]:
        """The bounds as bag stamps (ns) given the run's first step, None where open."""
        return (
            None if self.start is None else self.start.resolve(first_ns),
            None if self.end is None else self.end.resolve(first_ns),
        )

    def describe(self) -> str:
        """``--start A --end B`` as given (empty for the whole run)."""
        parts = []
        if self.start is not None:
            parts.append(f"--start {self.start}")
        if self.end is not None:
            parts.append(f"--end {self.end}")
        return " ".join(parts)


def parse_bound(text: str) -> TimeBound:
    """``"12.5"`` (s from the first step, >= 0) or ``"@1700000012.5"`` (bag time, s) as a bound.

    Raises:
        ValueError: Not a finite decimal number of seconds, or a negative relative bound.
    """
    absolute = text.startswith("@")
    body = text[1:] if absolute else text
    try:
        seconds = Decimal(body.strip())
    except InvalidOperation:
        raise ValueError(f"{text!r} is not a number of seconds (or @bag time in seconds)") from None
    if not seconds.is_finite():
        raise ValueError(f"{text!r} is not a finite number of seconds")
    if seconds < 0:
        raise ValueError(f"{text!r}: a time must be >= 0 s")
    return TimeBound(int((seconds * _NS).to_integral_value()), absolute)


def add_reading_options(parser: argparse.ArgumentParser, *, segments_help: str) -> None:
    """Add what every command reading a bag's steps takes: ``--quiet``, ``--segments``, ``--start/--end``."""
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--segments", action="store_true", help=segments_help)
    help_text = "s from the run's first step, or @bag time in s"
    parser.add_argument("--start", metavar="T", help=f"analyse from T on ({help_text})")
    parser.add_argument("--end", metavar="T", help=f"analyse up to T, excluded ({help_text})")


def window_from_options(options: argparse.Namespace) -> TimeWindow:
    """The window of parsed ``--start`` / ``--end``.

    Raises:
        ValueError: A bound that does not parse, or an end not after the start (same kind of bound).
    """
    start = None if options.start is None else parse_bound(options.start)
    end = None if options.end is None else parse_bound(options.end)
    if start is not None and end is not None and start.absolute == end.absolute and end.ns <= start.ns:
        raise ValueError(f"--end {end} must be after --start {start}")
    return TimeWindow(start, end)
