"""The stamp gate: whether a stamped input is new, a re-transmission, stale, too far ahead or a time jump.

Pure (no ROS); the policy is described in ``docs/NODES.md``.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Final

from smm_schema.ranges import bounds, check_bounds

__all__ = ["DEFAULT_CONTROL_PERIOD", "REFUSED", "Admission", "StampGate", "StampPolicy"]

DEFAULT_CONTROL_PERIOD: Final[float] = 1e-3
"""Default control period (s): 1 kHz, the paper's."""

_NS_PER_S: Final[int] = 1_000_000_000


@dataclass(frozen=True)
class StampPolicy:
    """How far a stamp may jump before it is refused, and when a jump is believed (``docs/NODES.md``).

    Attributes:
        max_ahead_periods: A stamp more than this many control periods ahead of the last answered one is
            refused (dropped_ahead), an integer in [1, 100000].
        clock_tolerance: A stamp more than this many seconds ahead of the node's clock (ROS time: sim time
            with use_sim_time) is refused (dropped_future), in [0.001, 3600] s; not checked while the
            clock reads 0 (sim time before the first /clock).
        resync_samples: After this many consecutive refused stamps that follow each other (each at or after
            the previous one, within max_ahead_periods), with no acceptable stamp in between, the node takes
            them for a genuine time jump and resynchronises, an integer in [2, 1000].
    """

    max_ahead_periods: int = field(default=100, metadata=bounds(1, 100_000))
    clock_tolerance: float = field(default=1.0, metadata=bounds(1e-3, 3600.0))
    resync_samples: int = field(default=5, metadata=bounds(2, 1000))

    def __post_init__(self) -> None:
        check_bounds(self)


class Admission(enum.Enum):
    """What to do with an incoming stamp, relative to the last answered stamp and the node's clock."""

    NEW = "new"
    """Newer than the last answered, within ``max_ahead_periods``: process it."""
    RESYNC = "resync"
    """Accepted after a time jump (the last answered mark was forgotten): process it, warn."""
    DUPLICATE = "duplicate"
    """Equal to the last answered: a re-transmission."""
    STALE = "stale"
    """Older than the last answered: refused."""
    AHEAD = "ahead"
    """More than ``max_ahead_periods`` ahead of the last answered: refused."""
    FUTURE = "future"
    """More than ``clock_tolerance`` ahead of the node's clock: refused, never a resynchronisation."""


REFUSED: Final[frozenset[Admission]] = frozenset({Admission.STALE, Admission.AHEAD, Admission.FUTURE})
"""Admissions whose input is dropped and counted."""


class StampGate:
    """Remember the last answered stamp and classify incoming ones (pure, no ROS; ``docs/NODES.md``).

    A refused stamp never moves the last answered mark. Refused stamps that form a consistent track of their
    own (non-decreasing, steps of at most ``max_ahead_periods``), ``resync_samples`` in a row with no
    acceptable stamp in between, are a time jump: the gate forgets the mark and answers RESYNC.

    Args:
        policy: The limits (default :class:`StampPolicy`).
        control_period: Control period (s), the unit of ``max_ahead_periods``.
    """

    def __init__(
        self, policy: StampPolicy | None = None, control_period: float = DEFAULT_CONTROL_PERIOD
    ) -> None:
        self._policy = policy if policy is not None else StampPolicy()
        self._control_period = control_period
        self._window_ns = self._tolerance_ns = 0
        self._set_limits()
        self._last_stamp_ns: int | None = None
        self._track_ns: int | None = None
        self._track_length = 0
        self.last_jump: tuple[int, int] | None = None
        """``(old mark, new stamp)`` (ns) of the last resynchronisation, None before any."""

    @property
    def policy(self) -> StampPolicy:
        """The limits; new ones apply from the next stamp."""
        return self._policy

    @policy.setter
    def policy(self, policy: StampPolicy) -> None:
        self._policy = policy
        self._set_limits()

    @property
    def control_period(self) -> float:
        """Control period (s), the unit of ``max_ahead_periods``."""
        return self._control_period

    @control_period.setter
    def control_period(self, control_period: float) -> None:
        self._control_period = control_period
        self._set_limits()

    def _set_limits(self) -> None:
        """The policy's limits in ns, once per change instead of per stamp."""
        self._window_ns = self._policy.max_ahead_periods * round(self._control_period * _NS_PER_S)
        self._tolerance_ns = round(self._policy.clock_tolerance * _NS_PER_S)

    @property
    def last_stamp_ns(self) -> int | None:
        """Stamp of the last answered measurement (ns), None before the first."""
        return self._last_stamp_ns

    @property
    def max_ahead_ns(self) -> int:
        """Largest accepted distance ahead of the last answered stamp (ns)."""
        return self._window_ns

    def classify(self, stamp_ns: int, now_ns: int | None = None) -> Admission:
        """Classify ``stamp_ns`` (ns) given the node's clock ``now_ns`` (ns; None or 0: not checked).

        Refused stamps advance the jump detection; RESYNC has already forgotten the last answered mark.
        """
        if now_ns and stamp_ns > now_ns + self._tolerance_ns:
            return Admission.FUTURE
        last = self._last_stamp_ns
        if last is None:
            return Admission.NEW
        if stamp_ns == last:
            return Admission.DUPLICATE
        window = self._window_ns
        if last < stamp_ns <= last + window:
            self._track_ns, self._track_length = None, 0
            return Admission.NEW
        track = self._track_ns
        follows = track is not None and track <= stamp_ns <= track + window
        self._track_length = self._track_length + 1 if follows else 1
        self._track_ns = stamp_ns
        if self._track_length >= self._policy.resync_samples:
            self.last_jump = (last, stamp_ns)
            self._last_stamp_ns = None
            self._track_ns, self._track_length = None, 0
            return Admission.RESYNC
        return Admission.STALE if stamp_ns < last else Admission.AHEAD

    def mark_answered(self, stamp_ns: int) -> None:
        """Record ``stamp_ns`` (ns) as answered.

        Raises:
            ValueError: ``stamp_ns`` is not newer than the last answered stamp.
        """
        if self._last_stamp_ns is not None and stamp_ns <= self._last_stamp_ns:
            raise ValueError(
                f"stamp {stamp_ns} ns is not newer than the last answered {self._last_stamp_ns} ns"
            )
        self._last_stamp_ns = stamp_ns

    def reset(self) -> None:
        """Forget the last answered stamp and any jump in progress (every stamp is NEW again)."""
        self._last_stamp_ns = None
        self._track_ns, self._track_length = None, 0
