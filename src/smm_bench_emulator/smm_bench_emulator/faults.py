"""Faults injected on the emulator's link, on request: drop, delay, duplicate, reorder, corrupt, silence.

Pure and seeded; the board-side faults (reboot, fault bits, supply pressure) are :class:`BoardCore`'s.
"""

from __future__ import annotations

import enum
from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ["LinkFault", "LinkFaults"]


class LinkFault(enum.Enum):
    """What happens to the next ``count`` outgoing feedback frames (``DROP_COMMANDS``: incoming commands)."""

    DROP = "drop"
    DELAY = "delay"
    DUPLICATE = "duplicate"
    REORDER = "reorder"
    CORRUPT = "corrupt"
    SILENT = "silent"
    DROP_COMMANDS = "drop_commands"


_OUTGOING = tuple(kind for kind in LinkFault if kind is not LinkFault.DROP_COMMANDS)


@dataclass
class _Active:
    kind: LinkFault
    remaining: int
    ticks: int


class LinkFaults:
    """Applies requested faults to frames, one call per frame.

    Args:
        seed: Seed of the corruption positions.
    """

    def __init__(self, seed: int = 0) -> None:
        self._rng = np.random.default_rng(seed)
        self._active: list[_Active] = []
        self._delayed: deque[tuple[int, bytes]] = deque()
        self._held: bytes | None = None
        self.applied: dict[LinkFault, int] = {}

    def request(self, kind: LinkFault | str, count: int = 1, ticks: int = 0) -> None:
        """Applies ``kind`` to the next ``count`` frames (``DELAY``: each held ``ticks`` ticks).

        Raises:
            ValueError: unknown kind, count < 1, or ticks < 0.
        """
        fault = LinkFault(kind)
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise ValueError(f"count must be an int >= 1, got {count!r}")
        if isinstance(ticks, bool) or not isinstance(ticks, int) or ticks < 0:
            raise ValueError(f"ticks must be an int >= 0, got {ticks!r}")
        self._active.append(_Active(fault, count, ticks))

    def clear(self) -> None:
        """Ends every requested fault (delayed and held frames are discarded)."""
        self._active.clear()
        self._delayed.clear()
        self._held = None

    def _take(self, kinds: tuple[LinkFault, ...]) -> _Active | None:
        for fault in self._active:
            if fault.kind in kinds:
                fault.remaining -= 1
                if fault.remaining <= 0:
                    self._active.remove(fault)
                self.applied[fault.kind] = self.applied.get(fault.kind, 0) + 1
                return fault
        return None

    def incoming(self, frame: bytes) -> bytes | None:
        """A received command frame, or None if it is to be dropped."""
        return None if self._take((LinkFault.DROP_COMMANDS,)) else frame

    def outgoing(self, frame: bytes, tick: int) -> list[bytes]:
        """Frames to send now at board tick ``tick`` for one feedback frame (possibly none, or several)."""
        out = [data for due, data in self._delayed if due <= tick]
        while self._delayed and self._delayed[0][0] <= tick:
            self._delayed.popleft()
        fault = self._take(_OUTGOING)
        kind = None if fault is None else fault.kind
        if kind in (LinkFault.DROP, LinkFault.SILENT):
            return out
        if kind is LinkFault.DELAY and fault is not None:
            self._delayed.append((tick + fault.ticks, frame))
            return out
        if kind is LinkFault.DUPLICATE:
            return [*out, frame, frame]
        if kind is LinkFault.CORRUPT:
            data = bytearray(frame)
            index = int(self._rng.integers(0, len(data)))
            data[index] ^= int(self._rng.integers(1, 256))
            return [*out, bytes(data)]
        if kind is LinkFault.REORDER:
            if self._held is None:
                self._held = frame
                fault_again = _Active(LinkFault.REORDER, 1, 0)
                self._active.insert(0, fault_again)  # the next frame goes out first, then this one
                return out
            held, self._held = self._held, None
            return [*out, frame, held]
        return [*out, frame]
