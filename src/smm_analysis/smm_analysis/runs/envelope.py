"""Per-column min/max envelope of long series, in bounded memory, so that no spike disappears from a figure.

Steps fall into at most ``columns`` columns of ``width`` consecutive steps each; when a new step would need
one column more, neighbouring columns are merged in pairs and the width doubles. Each column keeps, per
series, the least and greatest value of its steps (NaN ignored) and its first and last time. Drawn as one
line through every column's minimum and maximum, a single-step spike still reaches its value.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["DEFAULT_COLUMNS", "Envelope"]

FloatArray = NDArray[np.float64]
DEFAULT_COLUMNS = 2048
"""More than the pixels of a panel at the figures' size (400 px)."""


class Envelope:
    """Min/max of named series per column of steps.

    Args:
        columns: Most columns kept (even, >= 2).
    """

    def __init__(self, columns: int = DEFAULT_COLUMNS) -> None:
        if columns < 2 or columns % 2:
            raise ValueError(f"columns must be even and >= 2, got {columns}")
        self.capacity = columns
        self.width = 1
        self.used = 0
        self.steps = 0
        self.t_first = np.full(columns, np.nan)
        self.t_last = np.full(columns, np.nan)
        self.low: dict[str, FloatArray] = {}
        self.high: dict[str, FloatArray] = {}

    def _merge(self) -> None:
        """Halves the columns: each new column is two old ones."""
        half = self.capacity // 2
        self.t_first = np.concatenate([self.t_first[0::2], np.full(half, np.nan)])
        last = self.t_last.reshape(half, 2)
        self.t_last = np.concatenate(
            [np.where(np.isnan(last[:, 1]), last[:, 0], last[:, 1]), np.full(half, np.nan)]
        )
        for store, reduce in ((self.low, np.fmin), (self.high, np.fmax)):
            for name, values in store.items():
                pairs = values.reshape(half, 2)
                store[name] = np.concatenate([reduce(pairs[:, 0], pairs[:, 1]), np.full(half, np.nan)])
        self.width *= 2
        self.used = -(-self.steps // self.width)

    def add(self, t_s: FloatArray, series: dict[str, FloatArray]) -> None:
        """Adds the next steps: times (s), shape (n,), and each series' values there, shape (n,)."""
        n = t_s.size
        if n == 0:
            return
        while (self.steps + n - 1) // self.width >= self.capacity:
            self._merge()
        index = (self.steps + np.arange(n)) // self.width
        starts = np.concatenate([[0], np.nonzero(np.diff(index))[0] + 1])
        columns = index[starts]
        ends = np.concatenate([starts[1:], [n]]) - 1
        fresh = np.isnan(self.t_first[columns])
        self.t_first[columns] = np.where(fresh, t_s[starts], self.t_first[columns])
        self.t_last[columns] = t_s[ends]
        for name, values in series.items():
            for store, reduce in ((self.low, np.fmin), (self.high, np.fmax)):
                if name not in store:
                    store[name] = np.full(self.capacity, np.nan)
                with np.errstate(invalid="ignore"):
                    part = reduce.reduceat(values, starts)
                store[name][columns] = reduce(store[name][columns], part)
        self.steps += n
        self.used = int(columns[-1]) + 1

    def names(self) -> list[str]:
        """Series added so far."""
        return list(self.low)

    def line(self, name: str) -> tuple[FloatArray, FloatArray]:
        """X (s) and y of the line through each column's minimum then maximum (NaN where none)."""
        used = slice(0, self.used)
        first, last = self.t_first[used], self.t_last[used]
        x = np.column_stack([first, last]).ravel()
        low, high = self.low[name][used], self.high[name][used]
        y = np.column_stack([low, high]).ravel()
        return x, y

    def drawn(self, name: str) -> bool:
        """Whether the series has any finite value."""
        return name in self.low and bool(np.any(np.isfinite(self.low[name][: self.used])))
