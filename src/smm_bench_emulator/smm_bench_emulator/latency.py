"""Latency percentiles in bounded memory: a histogram of 1 us bins, whatever the run's length."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["LatencyHistogram"]

TOP_US = 100_000
"""Latencies from 0 to this many us get a bin each; longer ones share the last bin (their maximum is kept)."""
_BLOCK = 1000
"""Bins per block of the second level: a percentile sums 101 blocks and one block's bins, not 100,001 bins."""


class LatencyHistogram:
    """Counts latencies (ns) in 1 us bins; percentiles exact to the bin (the value rounded down to 1 us).

    800 KB whatever the run's length, where a list of every value grows by 1,000 values a second at 1 kHz.
    """

    def __init__(self) -> None:
        self._bins = np.zeros(TOP_US + 1, dtype=np.int64)
        self._blocks = np.zeros(TOP_US // _BLOCK + 1, dtype=np.int64)
        self.count = 0
        self.maximum_ns: int | None = None

    def add(self, value_ns: int) -> None:
        """Adds one latency (ns; a negative one counts as 0)."""
        value = max(int(value_ns), 0)
        index = min(value // 1000, TOP_US)
        self._bins[index] += 1
        self._blocks[index // _BLOCK] += 1
        self.count += 1
        self.maximum_ns = value if self.maximum_ns is None else max(self.maximum_ns, value)

    def percentile_us(self, q: float) -> float | None:
        """The ``q``-th percentile (0-100; inverted CDF: a value that was seen), in us; None before any."""
        if not self.count or self.maximum_ns is None:
            return None
        rank = max(1, math.ceil(q / 100.0 * self.count))
        totals = np.cumsum(self._blocks)
        block = int(np.searchsorted(totals, rank))
        start = block * _BLOCK
        before = int(totals[block - 1]) if block else 0
        index = start + int(np.searchsorted(np.cumsum(self._bins[start : start + _BLOCK]), rank - before))
        return self.maximum_ns / 1e3 if index >= TOP_US else float(index)
