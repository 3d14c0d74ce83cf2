"""Exact-time synchroniser of stamped inputs (pure Python, no ROS; ``message_filters`` is not available).

:class:`ExactTimeSynchronizer` returns the inputs of one stamp together once all are present, in stamp
order; what it drops and counts: docs/NODES.md, "Inputs of one stamp".
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Generic, TypeVar

__all__ = ["DEFAULT_MAX_PENDING", "ExactTimeSynchronizer", "Matched"]

ItemT = TypeVar("ItemT")

DEFAULT_MAX_PENDING = 10
"""Incomplete stamps held at most: the control-topic queue depth (10 samples, 10 ms at 1 kHz)."""


@dataclass(frozen=True)
class Matched(Generic[ItemT]):
    """All inputs of one stamp.

    Attributes:
        stamp_ns: The common stamp (ns).
        items: ``{input name: item}`` with exactly the synchroniser's inputs (read-only).
    """

    stamp_ns: int
    items: Mapping[str, ItemT]


class ExactTimeSynchronizer(Generic[ItemT]):
    """Match inputs with equal stamps.

    Args:
        inputs: Names of the required inputs, unique, at least one.
        max_pending: Most incomplete stamps held at once, >= 1.

    Raises:
        ValueError: no inputs, duplicate names, or ``max_pending`` < 1.
    """

    def __init__(self, inputs: Iterable[str], max_pending: int = DEFAULT_MAX_PENDING) -> None:
        if isinstance(max_pending, bool) or not isinstance(max_pending, int) or max_pending < 1:
            raise ValueError(f"max_pending must be an integer >= 1, got {max_pending!r}")
        self._max_pending = max_pending
        self._inputs: frozenset[str] = frozenset()
        self._pending: dict[int, dict[str, ItemT]] = {}
        self._last_matched_ns: int | None = None
        self.dropped = 0
        self.late = 0
        self.set_inputs(inputs)

    @property
    def inputs(self) -> frozenset[str]:
        """Names of the required inputs."""
        return self._inputs

    @property
    def pending_stamps(self) -> tuple[int, ...]:
        """Stamps (ns) with some but not all inputs, oldest first."""
        return tuple(sorted(self._pending))

    @property
    def last_matched_ns(self) -> int | None:
        """Stamp (ns) of the last complete set, None before the first."""
        return self._last_matched_ns

    def set_inputs(self, inputs: Iterable[str]) -> None:
        """Change the required inputs; pending stamps are discarded (not counted as dropped).

        Raises:
            ValueError: no inputs or duplicate names.
        """
        names = tuple(inputs)
        if not names:
            raise ValueError("a synchroniser needs at least one input")
        if len(set(names)) != len(names):
            raise ValueError(f"input names must be unique, got {names}")
        self._inputs = frozenset(names)
        self._pending.clear()

    def clear(self) -> None:
        """Discard pending stamps and forget the last matched stamp (counters are kept)."""
        self._pending.clear()
        self._last_matched_ns = None

    def add(self, name: str, stamp_ns: int, item: ItemT) -> Matched[ItemT] | None:
        """Add the input ``name`` for ``stamp_ns`` (ns).

        Returns:
            The complete set when this input completes ``stamp_ns``, else None.

        Raises:
            KeyError: ``name`` is not one of the inputs.
        """
        if name not in self._inputs:
            raise KeyError(f"unknown input {name!r}; inputs are {sorted(self._inputs)}")
        if self._last_matched_ns is not None and stamp_ns <= self._last_matched_ns:
            self.late += 1
            return None
        slot = self._pending.get(stamp_ns)
        if slot is None:
            slot = {}
            self._pending[stamp_ns] = slot
        slot[name] = item
        if len(slot) == len(self._inputs):
            return self._emit(stamp_ns)
        if len(self._pending) > self._max_pending:
            del self._pending[min(self._pending)]
            self.dropped += 1
        return None

    def _emit(self, stamp_ns: int) -> Matched[ItemT]:
        items = self._pending.pop(stamp_ns)
        older = [stamp for stamp in self._pending if stamp < stamp_ns]
        for stamp in older:
            del self._pending[stamp]
        self.dropped += len(older)
        self._last_matched_ns = stamp_ns
        return Matched(stamp_ns, MappingProxyType(items))
