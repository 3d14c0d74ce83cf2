"""Loop statistics as ros2_control's controller manager reports them: periodicity and execution time."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["LoopStatistics", "RunningFigures"]

_KEPT = 10_000
"""Execution times kept for the percentiles (the newest; 10 s at 1 kHz). The percentiles are taken in the
executor thread while the loop runs: numpy's partition of 10,000 values releases the GIL and takes well
under a period, where sorting a long Python list would hold the GIL, and so the loop, for milliseconds."""


@dataclass
class RunningFigures:
    """Count, mean, min, max and standard deviation of a series (Welford), in the series' unit."""

    count: int = 0
    mean: float = 0.0
    minimum: float = math.inf
    maximum: float = -math.inf
    _m2: float = 0.0

    def add(self, value: float) -> None:
        """Adds one value."""
        self.count += 1
        delta = value - self.mean
        self.mean += delta / self.count
        self._m2 += delta * (value - self.mean)
        self.minimum = min(self.minimum, value)
        self.maximum = max(self.maximum, value)

    @property
    def std(self) -> float:
        """Population standard deviation (0 below two values)."""
        return math.sqrt(self._m2 / self.count) if self.count > 1 else 0.0


class LoopStatistics:
    """Periodicity (time between admitted feedback frames) and execution time (receive -> send) in us."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forgets every figure (a new run)."""
        self.period_us = RunningFigures()
        self.execution_us = RunningFigures()
        self._last_rx_ns: int | None = None
        self._recent = np.zeros(_KEPT)
        self._kept = 0

    def on_tick(self, rx_ns: int, sent_ns: int) -> None:
        """One answered feedback frame: received at ``rx_ns``, its command sent at ``sent_ns`` (ns)."""
        if self._last_rx_ns is not None and rx_ns > self._last_rx_ns:
            self.period_us.add((rx_ns - self._last_rx_ns) / 1e3)
        self._last_rx_ns = rx_ns
        execution = (sent_ns - rx_ns) / 1e3
        self.execution_us.add(execution)
        self._recent[self._kept % _KEPT] = execution
        self._kept += 1

    def execution_percentile_us(self, q: float) -> float:
        """The ``q``-th percentile (0-100) of the kept execution times (us); NaN before any."""
        if not self._kept:
            return math.nan
        return float(np.percentile(self._recent[: min(self._kept, _KEPT)], q, method="inverted_cdf"))

    def values(self) -> dict[str, str]:
        """The figures as ``/diagnostics`` key-values (ros2_control's names, us)."""
        out: dict[str, str] = {}
        for name, figures in (("periodicity", self.period_us), ("execution_time", self.execution_us)):
            out[f"{name}.samples"] = str(figures.count)
            for label, value in (
                ("mean", figures.mean),
                ("min", figures.minimum),
                ("max", figures.maximum),
                ("std", figures.std),
            ):
                out[f"{name}.{label}_us"] = f"{value:.1f}" if figures.count else "nan"
        out["execution_time.p50_us"] = f"{self.execution_percentile_us(50):.1f}"
        out["execution_time.p99_us"] = f"{self.execution_percentile_us(99):.1f}"
        return out
