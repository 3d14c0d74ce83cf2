"""Loop latency of a recorded run: its quantiles and its empirical distribution (no rendering here)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["LatencySummary", "latency_cdf", "summarize_latency"]

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
