"""Feedback admission (session, duplicate, out-of-order, stale) and link statistics. Pure, no ROS.

Stale: the board ticks at a fixed period, so ``receive time - tick * period`` is constant for frames that
travel without delay; the smallest such offset seen is the board clock's estimate. A frame whose offset
exceeds it by more than ``stale_ns`` was delivered late (queued behind a host stall, a switch buffer...)
and is dropped. The estimate follows slow drift between the two clocks (``drift_ppm``).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from smm_schema.ranges import bounds, check_bounds

from smm_hw_bridge.protocol import FeedbackFrame, Reason, u32_diff

__all__ = ["AdmissionConfig", "FeedbackAdmission", "LinkStats"]


@dataclass(frozen=True)
class AdmissionConfig:
    """Admission of feedback frames.

    Attributes:
        period_ns: Board tick period (ns).
        stale_ns: Delivery delay beyond the fastest seen after which a frame is stale (ns).
        drift_ppm: Allowed drift between host and board clocks (parts per million).
    """

    period_ns: int = field(default=1_000_000, metadata=bounds(1, 1_000_000_000))
    stale_ns: int = field(default=20_000_000, metadata=bounds(1, 60_000_000_000))
    drift_ppm: float = field(default=200.0, metadata=bounds(0.0, 1e5, high_open=True))

    def __post_init__(self) -> None:
        check_bounds(self)


class FeedbackAdmission:
    """Decides whether a decoded feedback frame of the expected board session may be used."""

    def __init__(self, config: AdmissionConfig) -> None:
        self._config = config
        self.rejected: dict[Reason, int] = {}
        self._last_seq: int | None = None
        self._last_tick: int | None = None
        self._tick = 0
        self._epoch = 0
        self._offset: float | None = None
        self._last_rx: int | None = None

    def reset(self) -> None:
        """Forgets the sequence and clock history (a new session); counters are kept.

        The new session's unwrapped ticks continue after the old one's, so stamps never repeat.
        """
        self._epoch = self._tick + 1 if self._last_tick is not None else self._epoch
        self._last_seq = None
        self._last_tick = None
        self._offset = None
        self._last_rx = None

    def count(self, reason: Reason) -> None:
        """Counts a rejection decided elsewhere (parser, transport, session)."""
        self.rejected[reason] = self.rejected.get(reason, 0) + 1

    @property
    def tick(self) -> int:
        """Board tick of the last admitted frame, unwrapped, continued across sessions (0 before any)."""
        return self._tick

    def admit(self, frame: FeedbackFrame, rx_ns: int) -> Reason | None:
        """None if the frame may be used, else the reason it is dropped (and counted).

        Args:
            frame: A frame of the expected session (the caller checks the session).
            rx_ns: Host receive time (ns, monotonic).
        """
        if self._last_seq is not None:
            step = u32_diff(frame.seq, self._last_seq)
            if step == 0:
                self.count(Reason.DUPLICATE)
                return Reason.DUPLICATE
            if step < 0:
                self.count(Reason.OUT_OF_ORDER)
                return Reason.OUT_OF_ORDER
        tick = (
            self._epoch + frame.tick
            if self._last_tick is None
            else self._tick + u32_diff(frame.tick, self._last_tick)
        )
        offset = rx_ns - tick * self._config.period_ns
        if self._offset is not None and self._last_rx is not None:
            allowance = (rx_ns - self._last_rx) * self._config.drift_ppm * 1e-6
            self._offset = min(self._offset + allowance, offset)
        else:
            self._offset = offset
        self._last_rx = rx_ns
        self._last_seq = frame.seq
        self._last_tick = frame.tick
        self._tick = tick
        if offset - self._offset > self._config.stale_ns:
            self.count(Reason.STALE)
            return Reason.STALE
        return None


class LinkStats:
    """Packet loss from sequence gaps, the longest loss streak, and round-trip times.

    Args:
        window: Round-trip samples kept for the percentiles.
    """

    def __init__(self, window: int = 2000) -> None:
        self._rtt: deque[int] = deque(maxlen=window)
        self._sent: dict[int, int] = {}
        self.received = 0
        self.lost = 0
        self.longest_streak = 0
        self._last_seq: int | None = None

    def reset_sequence(self) -> None:
        """A new session: the next sequence number starts a new count of gaps."""
        self._last_seq = None
        self._sent.clear()

    def on_feedback(self, seq: int, applied_seq: int, rx_ns: int) -> None:
        """Counts an admitted frame and the gap before it, and closes the round trip of ``applied_seq``."""
        if self._last_seq is not None:
            gap = u32_diff(seq, self._last_seq) - 1
            if gap > 0:
                self.lost += gap
                self.longest_streak = max(self.longest_streak, gap)
        self._last_seq = seq
        self.received += 1
        sent = self._sent.pop(applied_seq, None)
        if sent is not None:
            self._rtt.append(rx_ns - sent)
        if len(self._sent) > 1000:
            self._sent.clear()

    def on_command_sent(self, seq: int, tx_ns: int) -> None:
        """Remembers when command ``seq`` left, to time its round trip."""
        self._sent[seq] = tx_ns

    @property
    def loss_fraction(self) -> float:
        """Lost / (lost + received) feedback frames, 0 before any."""
        total = self.lost + self.received
        return self.lost / total if total else 0.0

    def rtt_percentiles_ns(self) -> Mapping[str, float]:
        """``p50`` and ``p99`` of the round trip command sent -> feedback applying it (ns); NaN if none."""
        if not self._rtt:
            return {"p50": float("nan"), "p99": float("nan")}
        values = np.fromiter(self._rtt, dtype=np.float64)
        return {"p50": float(np.percentile(values, 50)), "p99": float(np.percentile(values, 99))}
