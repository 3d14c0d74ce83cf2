"""The sum numpy takes of a 1-D float64 array, fed in pieces: the same additions in the same order.

``np.sum`` adds a contiguous array pairwise: halves (cut at a multiple of 8) down to runs of at most 128
terms, each summed with eight accumulators. Knowing the number of terms before the first, the sum can be
taken as the terms arrive, in memory of one run plus a stack as deep as the halvings.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

__all__ = ["PAIRWISE_RUN", "PairwiseSum"]

PAIRWISE_RUN = 128
"""Longest run numpy sums without halving (``PW_BLOCKSIZE`` of its pairwise summation)."""


def _postfix(count: int) -> Iterator[int]:
    """The summation of ``count`` terms by numpy in postfix: a run's length (> 0), or 0: add the last two."""
    if count <= PAIRWISE_RUN:
        yield count
        return
    half = count // 2
    half -= half % 8
    yield from _postfix(half)
    yield from _postfix(count - half)
    yield 0


class PairwiseSum:
    """``float(np.sum(terms))`` of ``count`` terms (>= 1) added in pieces, in order.

    Raises (from :meth:`add`, :meth:`total`):
        ValueError: More terms than ``count``, or the total asked before all came.
    """

    def __init__(self, count: int) -> None:
        if count < 1:
            raise ValueError(f"count must be >= 1, got {count}")
        self.count = count
        self._operations = _postfix(count)
        self._next: int | None = next(self._operations)
        self._results: list[float] = []
        self._pending: list[NDArray[np.float64]] = []
        self._pending_size = 0
        self._seen = 0

    def add(self, terms: NDArray[np.float64]) -> None:
        """Adds the next terms, shape (n,)."""
        self._seen += terms.size
        if self._seen > self.count:
            raise ValueError(f"more than {self.count} terms")
        self._pending.append(terms)
        self._pending_size += terms.size
        while self._next is not None and 0 < self._next <= self._pending_size:
            pending = np.concatenate(self._pending) if len(self._pending) > 1 else self._pending[0]
            run, rest = pending[: self._next], pending[self._next :]
            self._results.append(float(np.sum(np.ascontiguousarray(run))))
            self._pending = [rest] if rest.size else []
            self._pending_size = rest.size
            self._next = next(self._operations, None)
            while self._next == 0:
                right = self._results.pop()
                self._results.append(self._results.pop() + right)
                self._next = next(self._operations, None)

    def total(self) -> float:
        """The sum of the ``count`` terms."""
        if self._next is not None:
            raise ValueError(f"{self._seen} of {self.count} terms added")
        return self._results[0]
