"""A run's used regressor rows reduced to normal equations per bootstrap block and joint, added as they come.

Everything the estimate needs (least squares, residual RMS, bootstrap, fit) is a sum over rows, so a run of
any length is a few numbers per block (docs/IDENTIFICATION.md, "Streaming").
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from smm_analysis.identification.data import PreparedRun
from smm_analysis.identification.filtering import Segment

__all__ = ["RunSums", "sums_of"]

FloatArray = NDArray[np.float64]
_WIDTH = 11


class RunSums:
    """Per bootstrap block (consecutive ``block`` s of a stretch) and joint: Y^T Y, Y^T tau, tau^T tau, rows.

    Feed each stretch as :meth:`start_stretch`, :meth:`add` its rows in order (in pieces if need be),
    :meth:`end_stretch`. Blocks without a used row are not kept.

    Args:
        name: The run, for reports.
        block: Length of a bootstrap block (s).
    """

    def __init__(self, name: str, block: float) -> None:
        self.name = name
        self.block = block
        self.ids: list[int] = []
        self.grams: list[FloatArray] = []  # each (2, 11, 11)
        self.moments: list[FloatArray] = []  # each (2, 11)
        self.squares: list[FloatArray] = []  # each (2,)
        self.counts: list[NDArray[np.int64]] = []  # each (2,)
        self.largest = 0.0
        self._next = 0
        self._origin = 0.0
        self._last = -1

    def start_stretch(self, origin: float) -> None:
        """A new stretch whose first row is at ``origin`` (s since the run's first stamp)."""
        self._origin = origin
        self._last = self._next - 1

    def add(self, rows: Segment) -> None:
        """The stretch's next rows (their ``columns``, ``torque``, ``use`` and ``time``)."""
        if rows.time.size == 0:
            return
        ids = self._next + ((rows.time - self._origin) // self.block).astype(np.int64)
        self._last = int(ids[-1])
        bounds = np.flatnonzero(np.diff(ids)) + 1
        for begin, end in zip([0, *bounds.tolist()], [*bounds.tolist(), ids.size], strict=True):
            use = rows.use[begin:end]
            if not use.any():
                continue
            gram = np.zeros((2, _WIDTH, _WIDTH))
            moment = np.zeros((2, _WIDTH))
            square = np.zeros(2)
            for joint in (0, 1):
                y = rows.columns[begin:end][use[:, joint], joint, :]
                tau = rows.torque[begin:end][use[:, joint], joint]
                gram[joint] = y.T @ y
                moment[joint] = y.T @ tau
                square[joint] = tau @ tau
                if tau.size:
                    self.largest = max(self.largest, float(np.abs(tau).max()))
            count = use.sum(axis=0).astype(np.int64)
            block_id = int(ids[begin])
            if self.ids and self.ids[-1] == block_id:
                self.grams[-1] += gram
                self.moments[-1] += moment
                self.squares[-1] += square
                self.counts[-1] += count
            else:
                self.ids.append(block_id)
                self.grams.append(gram)
                self.moments.append(moment)
                self.squares.append(square)
                self.counts.append(count)

    def end_stretch(self) -> None:
        """The stretch is complete: the next one starts a new block."""
        self._next = self._last + 1

    @property
    def rows(self) -> int:
        """Joint rows used."""
        return int(sum(int(count.sum()) for count in self.counts))

    def totals(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Sums over the blocks per joint: Y^T Y (2, 11, 11), Y^T tau (2, 11), tau^T tau (2,), rows (2,)."""
        if not self.ids:
            return np.zeros((2, _WIDTH, _WIDTH)), np.zeros((2, _WIDTH)), np.zeros(2), np.zeros(2)
        return (
            np.sum(self.grams, axis=0),
            np.sum(self.moments, axis=0),
            np.sum(self.squares, axis=0),
            np.sum(self.counts, axis=0).astype(np.float64),
        )

    def nrmse(self, theta: FloatArray) -> tuple[float, float]:
        """RMS(tau - Y theta) / RMS(tau) per joint over the used rows (NaN for a joint without rows)."""
        gram, moment, square, count = self.totals()
        values = []
        for joint in (0, 1):
            if count[joint] == 0:
                values.append(math.nan)
                continue
            residual = square[joint] - 2.0 * theta @ moment[joint] + theta @ gram[joint] @ theta
            values.append(math.sqrt(max(float(residual), 0.0) / float(square[joint])))
        return values[0], values[1]


def sums_of(run: PreparedRun, block: float) -> RunSums:
    """The sums of a run prepared in memory."""
    sums = RunSums(run.name, block)
    for segment in run.segments:
        sums.start_stretch(float(segment.time[0]))
        sums.add(segment)
        sums.end_stretch()
    return sums
