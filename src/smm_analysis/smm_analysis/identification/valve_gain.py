"""The valve's gain per direction: measured (load pressure) over modelled torque, with bootstrap intervals.

Method and why it separates gain from inertia: docs/IDENTIFICATION.md, "Measured torque".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from smm_analysis.errors import NotExcitingError

__all__ = ["DIRECTIONS", "GainSums", "ValveGain", "estimate_gain"]

FloatArray = NDArray[np.float64]
DIRECTIONS = ("positive", "negative")
"""Directions of the modelled torque, in the order of the gain arrays' last axis."""
OPEN_FRACTION = 0.1
"""Rows whose |modelled torque| is below this fraction of the joint's largest are left out (overlap, lag)."""
MIN_ROWS = 200
"""Rows a joint and direction need for an estimate."""


@dataclass
class GainSums:
    """Per bootstrap block: sum of model * measured, model^2 and rows, per joint and direction (b, 2, 2).

    Args:
        block: Length of a bootstrap block (s), > 0.
        peak: Largest |modelled torque| of the run per joint (N m), shape (2,).
    """

    block: float
    peak: FloatArray
    cross: list[FloatArray] = field(default_factory=list)
    square: list[FloatArray] = field(default_factory=list)
    rows: list[FloatArray] = field(default_factory=list)

    def add(self, time: FloatArray, measured: FloatArray, model: FloatArray) -> None:
        """Adds steps: time since the run's start (s), (n,); measured and modelled torque (N m), (n, 2)."""
        index = np.floor(time / self.block).astype(np.int64)
        needed = int(index.max()) + 1 if index.size else 0
        while len(self.cross) < needed:
            for store in (self.cross, self.square, self.rows):
                store.append(np.zeros((2, 2)))
        open_rows = np.abs(model) >= OPEN_FRACTION * self.peak
        for d, positive in enumerate((model > 0.0, model < 0.0)):
            use = open_rows & positive
            for j in (0, 1):
                picked = index[use[:, j]]
                if picked.size == 0:
                    continue
                m, tau = model[use[:, j], j], measured[use[:, j], j]
                for target, values in (
                    (self.cross, m * tau),
                    (self.square, m * m),
                    (self.rows, np.ones_like(m)),
                ):
                    sums = np.bincount(picked, weights=values, minlength=needed)
                    for block in np.flatnonzero(sums):
                        target[block][j, d] += sums[block]

    def arrays(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(cross, square, rows), each (b, 2, 2), blocks without rows dropped."""
        if not self.rows:
            empty = np.zeros((0, 2, 2))
            return empty, empty, empty
        rows = np.array(self.rows)
        kept = rows.sum(axis=(1, 2)) > 0
        return np.array(self.cross)[kept], np.array(self.square)[kept], rows[kept]


@dataclass(frozen=True)
class ValveGain:
    """Measured over modelled torque per joint and direction of the modelled torque.

    Attributes:
        ratio: Least-squares ratio through the origin (alpha, beta) x (positive, negative), shape (2, 2).
        interval: 95 % block-bootstrap percentile intervals, shape (2, 2, 2) (last axis: low, high).
        rows: Rows used per joint and direction, shape (2, 2).
    """

    ratio: FloatArray
    interval: FloatArray
    rows: FloatArray


def estimate_gain(runs: Sequence[GainSums], bootstrap: int, seed: int) -> ValveGain:
    """The ratio per joint and direction from the runs' block sums, with ``bootstrap`` block replicates.

    Raises:
        NotExcitingError: A joint and direction with fewer than :data:`MIN_ROWS` open rows.
    """
    parts = [run.arrays() for run in runs]
    cross, square, rows = (np.concatenate([part[k] for part in parts]) for k in range(3))
    counts = rows.sum(axis=0)
    thin = [
        f"{joint} {direction} ({int(counts[j, d])} rows)"
        for j, joint in enumerate(("alpha", "beta"))
        for d, direction in enumerate(DIRECTIONS)
        if counts[j, d] < MIN_ROWS
    ]
    if thin:
        raise NotExcitingError(
            f"the measured torque cannot give the valve's gain for {', '.join(thin)}: each joint needs "
            f"{MIN_ROWS} rows with the valve open ({OPEN_FRACTION:.0%} of its largest torque) in each "
            "direction; record the excite scenario"
        )
    ratio = cross.sum(axis=0) / square.sum(axis=0)
    generator = np.random.default_rng(seed)
    blocks = cross.shape[0]
    replicates = np.empty((bootstrap, 2, 2))
    for index in range(bootstrap):
        weights = np.bincount(generator.integers(0, blocks, blocks), minlength=blocks)
        top, bottom = np.tensordot(weights, cross, axes=1), np.tensordot(weights, square, axes=1)
        replicates[index] = np.divide(top, bottom, out=np.full((2, 2), math.nan), where=bottom > 0)
    interval = np.stack(
        [np.nanpercentile(replicates, 2.5, axis=0), np.nanpercentile(replicates, 97.5, axis=0)], axis=-1
    )
    return ValveGain(ratio=ratio, interval=interval, rows=counts)
