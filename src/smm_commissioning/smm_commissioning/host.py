"""The commissioning host over a :class:`Device`: answers every feedback, disabled or with open-loop codes.

No bridge loop: the steps command raw valve codes in the link's units (the frame board's D/A codes, the
CANopen valves' spool setpoints), one feedback at a time, and record every exchange.
"""

from __future__ import annotations

import dataclasses
import secrets
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final, TypeVar, cast

import numpy as np
from smm_hw_bridge.bridge_config import BridgeConfig
from smm_hw_bridge.canopen_device import CanopenDevice
from smm_hw_bridge.cia408 import SPOOL_FULL_SCALE
from smm_hw_bridge.device import Device, Feedback, ValveCommand
from smm_hw_bridge.protocol import CODE_MAX, CommandFlag, CommandFrame, FeedbackFrame
from smm_hw_bridge.valve_output import ValveOutputConfig

from smm_commissioning.errors import LinkLostError

__all__ = [
    "FULL_SCALE",
    "RECORD_COLUMNS",
    "BenchHost",
    "in_link_units",
    "in_units",
    "link_bridge",
    "link_of",
    "valve_units",
]

ConfigT = TypeVar("ConfigT")
FULL_SCALE: Final[dict[str, int]] = {"frame": CODE_MAX, "canopen": SPOOL_FULL_SCALE}
"""The valve output at 100 % per link: the frame board's D/A code, the CiA 408 spool setpoint (0x6300:01)."""

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
        device: The opened bench; its link's full scale bounds every code (:data:`FULL_SCALE`).
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
        self.code_max = FULL_SCALE[link_of(device)]
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
                    f"no feedback from the bench within {self.timeout_s:g} s: check its power, cable and "
                    "address (the board's, or each CANopen node's id and bit rate)"
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
            applied = (self._clip(codes[0]), self._clip(codes[1]))
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

    def make_safe(self) -> str | None:
        """Disabled frames for a few ticks, then the device's own means (a dead link's errors swallowed).

        Returns None, or what the device could not do (a CANopen valve not told DISABLED by SDO).
        """
        try:
            for _ in range(3):
                self.answer(None)
        except (LinkLostError, OSError):
            pass
        finally:
            untold = self.device.make_safe()
        return untold

    def _clip(self, code: int) -> int:
        return max(-self.code_max, min(self.code_max, int(code)))

    def record(self) -> np.ndarray:
        """Every exchange so far, shape (n, len(RECORD_COLUMNS)), int64."""
        return np.asarray(self.rows, dtype=np.int64).reshape(-1, len(RECORD_COLUMNS))

    def save(self, path: Path) -> Path:
        """Writes :meth:`record` as a compressed ``.npz`` (``record`` and ``columns``); returns ``path``."""
        np.savez_compressed(path, record=self.record(), columns=np.asarray(RECORD_COLUMNS))
        return path


def link_of(device: Device) -> str:
    """``canopen`` for the CANopen master (a real bus or the emulated bench), else ``frame``."""
    return "canopen" if isinstance(device, CanopenDevice) else "frame"


def in_link_units(codes: int, link: str) -> int:
    """``codes`` of the frame board's D/A in ``link``'s units: the same fraction of full scale, at least 1."""
    return max(round(codes * FULL_SCALE[link] / CODE_MAX), 1)


def in_units(config: ConfigT, link: str, names: tuple[str, ...]) -> ConfigT:
    """Dataclass ``config`` with its code fields ``names`` (frame board D/A codes) in ``link``'s units."""
    replaced: ConfigT = dataclasses.replace(
        cast(Any, config), **{name: in_link_units(getattr(config, name), link) for name in names}
    )
    return replaced


def valve_units(link: str) -> dict[str, list[float]]:
    """``bridge.valve.*`` limits in ``link``'s units (none on the frame link, where they are the defaults).

    The code and rate limits of the frame link's defaults scaled to the link's full scale.
    """
    if link == "frame":
        return {}
    scale = FULL_SCALE[link] / CODE_MAX
    default = ValveOutputConfig()
    return {
        "bridge.valve.code_limit": [round(limit * scale) for limit in default.code_limit],
        "bridge.valve.rate_limit": [rate * scale for rate in default.rate_limit],
    }


def link_bridge(link: str) -> BridgeConfig:
    """The bridge config a ``link`` device is opened with: its code limit at the link's full scale."""
    limits = valve_units(link).get("bridge.valve.code_limit", [CODE_MAX, CODE_MAX])
    return BridgeConfig(valve=ValveOutputConfig(code_limit=(int(limits[0]), int(limits[1]))))
