"""A one-line progress bar on stderr (redrawn in place on a terminal, every 10 % otherwise)."""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["Progress"]


class Progress:
    """Progress of ``total`` units of work labelled ``label``; call it with the units done so far.

    Args:
        label: What is being done.
        total: Units of work (messages, steps).
        stream: Where to draw (default: stderr at call time).
        enabled: Draw at all (off for ``--quiet`` or JSON output).
    """

    def __init__(self, label: str, total: int, stream: TextIO | None = None, *, enabled: bool = True) -> None:
        self.label = label
        self.total = max(total, 1)
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last_decile = -1
        self._start = time.monotonic()
        self._last_draw = 0.0

    def __call__(self, done: int, total: int | None = None) -> None:
        """Reports ``done`` units (and a new total, if given)."""
        if total is not None:
            self.total = max(total, 1)
        if not self.enabled:
            return
        fraction = min(done / self.total, 1.0)
        now = time.monotonic()
        if self._tty:
            if now - self._last_draw < 0.1 and done < self.total:
                return
            self._last_draw = now
            filled = int(30 * fraction)
            bar = "#" * filled + "-" * (30 - filled)
            rate = done / max(now - self._start, 1e-9)
            self.stream.write(f"\r{self.label} [{bar}] {100 * fraction:5.1f} % {rate:,.0f}/s")
            if done >= self.total:
                self.stream.write("\n")
            self.stream.flush()
            return
        decile = int(10 * fraction)
        if decile > self._last_decile:
            self._last_decile = decile
            self.stream.write(f"{self.label}: {100 * fraction:.0f} % ({done}/{self.total})\n")
            self.stream.flush()
