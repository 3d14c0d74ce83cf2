"""The commissioning host over a :class:`Device`: answers every feedback, disabled or with open-loop codes.

No bridge loop: the steps command raw D/A codes, one feedback at a time, and record every exchange.
"""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from smm_hw_bridge.device import Device, Feedback, ValveCommand
from smm_hw_bridge.protocol import CODE_MAX, CommandFlag, CommandFrame, FeedbackFrame

from smm_commissioning.errors import LinkLostError

__all__ = ["RECORD_COLUMNS", "BenchHost"]

RECORD_COLUMNS = (
    "tick",
    "counts_alpha",
    "counts_beta",
    "adc0",
    "adc1",
    "adc2",
    "adc3",
    "status",
    "faults",
    "code_alpha",
    "code_beta",
    "enabled",
)
"""Columns of :attr:`BenchHost.record`: the feedback, then the command that answered it."""


class BenchHost:
    """Reads the board's feedback and answers each one; the output stays disabled unless asked.

    Args:
        device: The opened bench.
        validity: Ticks after the answered feedback during which the board may apply a command.
        timeout_s: No feedback for this long -> :class:`LinkLostError`.
        clock: Monotonic clock (s), for the timeout.
    """

    def __init__(
        self,
        device: Device,
        validity: int = 10,
        timeout_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.device = device
        self.validity = validity
        self.timeout_s = timeout_s
        self._clock = clock
        self.session = secrets.randbelow(0xFFFF_FFFE) + 1
        self._seq = 0
        self.board_session: int | None = None
        self.feedback: FeedbackFrame | None = None
        self.rows: list[tuple[int, ...]] = []
        self.enabled_ever = False
        """True once an enabled command was sent (probe checks it never is)."""

    def next(self) -> Feedback:
        """The next feedback frame (reasons of refused frames are skipped).

        Raises:
            LinkLostError: None within the timeout, or the board restarted (a new session).
        """
        deadline = self._clock() + self.timeout_s
        while True:
            reading = self.device.read(min(0.05, self.timeout_s))
            if isinstance(reading, FeedbackFrame):
                if self.board_session is None:
                    self.board_session = reading.session
                elif reading.session != self.board_session:
                    raise LinkLostError("the board restarted (a new session): the step stopped, output null")
                self.feedback = reading
                return reading
            if self._clock() > deadline:
                raise LinkLostError(
                    f"no feedback from the board within {self.timeout_s:g} s: check its power, cable and "
                    "address"
                )

    def answer(self, codes: tuple[int, int] | None) -> Feedback:
        """Answers the last feedback with ``codes`` enabled (None: disabled); returns the next feedback."""
        if self.feedback is None:
            self.next()
        last = self.feedback
        assert last is not None
        flags = 0
        applied = (0, 0)
        if codes is not None:
            applied = (_clip(codes[0]), _clip(codes[1]))
            flags = int(CommandFlag.ENABLE)
            self.enabled_ever = True
        self._seq = (self._seq + 1) & 0xFFFF_FFFF
        command: ValveCommand = CommandFrame(
            session=self.session,
            seq=self._seq,
            board_session=last.session,
            answers_seq=last.seq,
            answers_tick=last.tick,
            flags=flags,
            validity=self.validity,
            codes=applied,
        )
        self.device.write(command)
        self.rows.append(
            (last.tick, *last.counts, *last.adc, last.status, last.faults, *applied, int(codes is not None))
        )
        return self.next()

    def hold(self, ticks: int) -> list[Feedback]:
        """Answers ``ticks`` feedbacks disabled (the valves held); returns them."""
        return [self.answer(None) for _ in range(ticks)]

    def make_safe(self) -> None:
        """Disabled frames for a few ticks, then the device's own means (a dead link's errors swallowed)."""
        try:
            for _ in range(3):
                self.answer(None)
        except (LinkLostError, OSError):
            pass
        finally:
            self.device.make_safe()

    def record(self) -> np.ndarray:
        """Every exchange so far, shape (n, len(RECORD_COLUMNS)), int64."""
        return np.asarray(self.rows, dtype=np.int64).reshape(-1, len(RECORD_COLUMNS))

    def save(self, path: Path) -> Path:
        """Writes :meth:`record` as a compressed ``.npz`` (``record`` and ``columns``); returns ``path``."""
        np.savez_compressed(path, record=self.record(), columns=np.asarray(RECORD_COLUMNS))
        return path


def _clip(code: int) -> int:
    return max(-CODE_MAX, min(CODE_MAX, int(code)))
