"""Samples left out of identification, found while the samples are fed in order: saturation and the stops.

Both are runs of consecutive samples (plateaus) judged against whole-run extremes, so a stream finds the
extremes in one pass and the runs in the next; the runs are kept as intervals (docs/IDENTIFICATION.md).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["Intervals", "Plateaus", "Saturation", "Stops", "flagged_count", "flags_of"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Intervals = list[tuple[int, int]]
"""Sample intervals [start, stop), sorted, not overlapping."""
# A joint at a stop: within this fraction of its range from an extreme, |q'| below STOP_VELOCITY.
STOP_BAND = 0.01
STOP_VELOCITY = 0.02


class Plateaus:
    """Runs of >= ``min_samples`` consecutive flagged samples, fed block by block in sample order.

    ``inner_only``: runs touching the first or the last sample are not counted (rest before or after).
    """

    def __init__(self, min_samples: int, *, inner_only: bool = False) -> None:
        self.min_samples = min_samples
        self.inner_only = inner_only
        self.position = 0
        self.start: int | None = None
        self.found: Intervals = []

    def _close(self, begin: int, end: int, *, at_end: bool) -> None:
        if end - begin >= self.min_samples and not (self.inner_only and (begin == 0 or at_end)):
            self.found.append((begin, end))

    def feed(self, flags: BoolArray) -> None:
        """The next samples' flags, shape (n,)."""
        n = int(flags.size)
        if n == 0:
            return
        if self.start is not None and not flags[0]:
            self._close(self.start, self.position, at_end=False)
            self.start = None
        edges = np.flatnonzero(np.diff(np.concatenate(([0], flags.astype(np.int8), [0]))))
        for begin, end in zip(edges[0::2].tolist(), edges[1::2].tolist(), strict=True):
            first = self.start if begin == 0 and self.start is not None else self.position + begin
            self.start = None
            if end == n:
                self.start = first
            else:
                self._close(first, self.position + end, at_end=False)
        self.position += n

    def finish(self) -> Intervals:
        """The runs found, once every sample was fed."""
        if self.start is not None:
            self._close(self.start, self.position, at_end=True)
            self.start = None
        return self.found


def _union(parts: list[Intervals]) -> Intervals:
    merged: Intervals = []
    for begin, end in sorted(interval for part in parts for interval in part):
        if merged and begin <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], end))
        else:
            merged.append((begin, end))
    return merged


def flags_of(joints: tuple[Intervals, Intervals], start: int, stop: int) -> BoolArray:
    """Flags of samples [start, stop) from each joint's intervals, shape (stop - start, 2)."""
    flags = np.zeros((stop - start, 2), dtype=bool)
    for joint, intervals in enumerate(joints):
        for begin, end in intervals:
            if end > start and begin < stop:
                flags[max(begin, start) - start : min(end, stop) - start, joint] = True
    return flags


def flagged_count(joints: tuple[Intervals, Intervals]) -> NDArray[np.int64]:
    """Flagged samples per joint, shape (2,)."""
    return np.array([sum(end - begin for begin, end in intervals) for intervals in joints], dtype=np.int64)


class Saturation:
    """Torque at its largest magnitude, or commanded beyond it, for ``min_samples`` or more.

    Args:
        peak: Largest |applied torque| of the whole run per joint (N m), shape (2,).
        spread: Its peak-to-peak per joint (N m), shape (2,); a constant torque is not a clipped one.
        min_samples: Least length of a plateau (samples).
    """

    def __init__(self, peak: FloatArray, spread: FloatArray, min_samples: int) -> None:
        self.peak = peak
        self.tolerance = 1e-9 * np.maximum(peak, 1e-12)
        self.driven = spread > self.tolerance
        self.at_peak = [Plateaus(min_samples) for _ in (0, 1)]
        self.beyond = [Plateaus(min_samples) for _ in (0, 1)]

    def feed(self, torque: FloatArray, command: FloatArray | None) -> None:
        """The next samples: applied torque and the command, if known (N m), shape (n, 2)."""
        for joint in (0, 1):
            if self.driven[joint]:
                magnitude = np.abs(torque[:, joint])
                self.at_peak[joint].feed(np.abs(magnitude - self.peak[joint]) <= self.tolerance[joint])
            if command is not None:
                self.beyond[joint].feed(np.abs(command[:, joint]) > 1.01 * self.peak[joint])

    def finish(self) -> tuple[Intervals, Intervals]:
        """Saturated samples per joint."""
        alpha, beta = (_union([self.at_peak[j].finish(), self.beyond[j].finish()]) for j in (0, 1))
        return alpha, beta


class Stops:
    """A joint held at an extreme of its range, |q'| small, for ``min_samples`` or more (not at the ends).

    Args:
        low: Least smoothed position of the whole run per joint (rad), shape (2,).
        high: Greatest, shape (2,).
        min_samples: Least length of a hold (samples).
    """

    def __init__(self, low: FloatArray, high: FloatArray, min_samples: int) -> None:
        self.extremes = (low, high)
        self.band = STOP_BAND * np.maximum(high - low, 1e-9)
        self.held = [[Plateaus(min_samples, inner_only=True) for _ in (0, 1)] for _ in (0, 1)]

    def feed(self, smooth: FloatArray, velocity: FloatArray) -> None:
        """The next samples: smoothed position (rad) and velocity (rad/s), shape (n, 2)."""
        slow = np.abs(velocity) < STOP_VELOCITY
        for side, extreme in enumerate(self.extremes):
            near = slow & (np.abs(smooth - extreme) <= self.band)
            for joint in (0, 1):
                self.held[side][joint].feed(near[:, joint])

    def finish(self) -> tuple[Intervals, Intervals]:
        """Samples at a stop per joint."""
        alpha, beta = (_union([self.held[side][j].finish() for side in (0, 1)]) for j in (0, 1))
        return alpha, beta
