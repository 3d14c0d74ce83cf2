"""Loop latency of a recorded run: its quantiles and its empirical distribution (no rendering here)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["LatencySketch", "LatencySummary", "latency_cdf", "summarize_latency"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LatencySummary:
    """Quantiles of the loop latency (ms): command receive time minus its measurement's receive time."""

    p50_ms: float
    p99_ms: float
    max_ms: float


def _milliseconds(latency_ns: NDArray[np.int64]) -> FloatArray:
    values = np.asarray(latency_ns)
    if values.ndim != 1 or values.size == 0:
        raise ValueError(f"latency_ns must be a non-empty 1-D array, got shape {values.shape}")
    return values.astype(np.float64) / 1e6


def summarize_latency(latency_ns: NDArray[np.int64]) -> LatencySummary:
    """Median, 99th percentile (linear interpolation, numpy's default) and maximum, in ms."""
    values = _milliseconds(latency_ns)
    return LatencySummary(
        p50_ms=float(np.median(values)), p99_ms=float(np.percentile(values, 99)), max_ms=float(values.max())
    )


def latency_cdf(latency_ns: NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
    """Empirical CDF: sorted latencies (ms), shape (N,), and the fraction of steps at or below each, (N,)."""
    values = np.sort(_milliseconds(latency_ns))
    return values, np.arange(1, values.size + 1, dtype=np.float64) / values.size


SKETCH_RELATIVE_ERROR = 1e-3
"""Bound of :class:`LatencySketch`'s quantiles: relative, for |latency| >= :data:`SKETCH_EXACT_BELOW_NS`."""
SKETCH_EXACT_BELOW_NS = 1_000
"""Latencies of smaller magnitude (ns) are counted exactly."""
_GAMMA = (1.0 + SKETCH_RELATIVE_ERROR) / (1.0 - SKETCH_RELATIVE_ERROR)
_LOG_GAMMA = math.log(_GAMMA)


class LatencySketch:
    """Loop latency counted in buckets of bounded memory (a relative-error sketch, as DDSketch).

    A latency v with |v| >= 1 us falls in bucket i = ceil(log_gamma(|v| / 1 us)) of its sign, whose
    representative 2 gamma^i / (1 + gamma) us is within :data:`SKETCH_RELATIVE_ERROR` of every value of
    the bucket; smaller ones are kept exactly. The quantile at p is numpy's (linear between the order
    statistics at floor and ceil of p (n - 1)) with each order statistic replaced by its representative, so
    it is within the relative bound of numpy's value. Minimum, maximum and count are exact.
    """

    def __init__(self) -> None:
        self.counts: dict[int, int] = {}
        self.count = 0
        self.minimum: int | None = None
        self.maximum: int | None = None

    def add(self, latency_ns: NDArray[np.int64]) -> None:
        """Counts latencies (ns), shape (n,)."""
        values = np.asarray(latency_ns, dtype=np.int64)
        if values.size == 0:
            return
        keys, counts = np.unique(_keys(values), return_counts=True)
        for key, count in zip(keys.tolist(), counts.tolist(), strict=True):
            self.counts[key] = self.counts.get(key, 0) + count
        self.count += int(values.size)
        low, high = int(values.min()), int(values.max())
        self.minimum = low if self.minimum is None else min(self.minimum, low)
        self.maximum = high if self.maximum is None else max(self.maximum, high)

    def _sorted(self) -> tuple[FloatArray, NDArray[np.int64]]:
        keys = np.array(sorted(self.counts, key=_representative_ns), dtype=np.int64)
        values = np.array([_representative_ns(int(key)) for key in keys])
        return values, np.cumsum([self.counts[int(key)] for key in keys])

    def quantile_ms(self, p: float) -> float:
        """The p-quantile (ms), p in [0, 1], within the stated bound of ``np.percentile(..., 100 p)``."""
        if self.count == 0:
            raise ValueError("no latencies counted")
        values, cumulative = self._sorted()
        position = p * (self.count - 1)
        below = math.floor(position)
        above = min(below + 1, self.count - 1)
        low = float(values[int(np.searchsorted(cumulative, below, side="right"))])
        high = float(values[int(np.searchsorted(cumulative, above, side="right"))])
        return (low + (position - below) * (high - low)) / 1e6

    def summary(self) -> LatencySummary:
        """Median, 99th percentile (within the bound) and exact maximum (ms)."""
        assert self.maximum is not None
        return LatencySummary(self.quantile_ms(0.5), self.quantile_ms(0.99), self.maximum / 1e6)

    def cdf(self) -> tuple[FloatArray, FloatArray]:
        """Bucket representatives (ms), sorted, and the fraction of steps at or below each."""
        values, cumulative = self._sorted()
        return values / 1e6, cumulative.astype(np.float64) / self.count


def _keys(values: NDArray[np.int64]) -> NDArray[np.int64]:
    """Bucket keys: the value itself below 1 us in magnitude, else sign * (1e9 + bucket index)."""
    magnitude = np.abs(values).astype(np.float64)
    exact = magnitude < SKETCH_EXACT_BELOW_NS
    index = np.ceil(np.log(np.maximum(magnitude, 1.0) / SKETCH_EXACT_BELOW_NS) / _LOG_GAMMA).astype(np.int64)
    keys = np.sign(values) * (_OFFSET + index)
    return np.where(exact, values, keys)


_OFFSET = 1_000_000_000


def _representative_ns(key: int) -> float:
    if abs(key) < _OFFSET:
        return float(key)
    index = abs(key) - _OFFSET
    value = SKETCH_EXACT_BELOW_NS * 2.0 * _GAMMA**index / (1.0 + _GAMMA)
    return math.copysign(value, key)
