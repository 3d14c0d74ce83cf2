"""Control rates below the board's tick: the divider N, which ticks are control ticks, the stretched limits.

The board ticks at 1 kHz whatever the control rate; the controller steps on every Nth tick and the board
holds each command in between. The rule for a command's validity and why: docs/LAUNCH.md, "Control rate".
Pure, no ROS.
"""

from __future__ import annotations

import math
from typing import Final

__all__ = [
    "BOARD_TICK_HZ",
    "CONTROL_RATES_HZ",
    "MAX_DIVIDER",
    "control_divider",
    "held_ticks",
    "in_flight_ticks",
    "is_control_tick",
]

BOARD_TICK_HZ: Final[int] = 1000
"""The I/O board's tick (Hz): its I/O, its hold and its watchdog run at this rate at every control rate."""
CONTROL_RATES_HZ: Final[tuple[int, ...]] = (1000, 500, 250, 200, 100)
"""The control rates ``smm-launch --control-rate`` offers (Hz), each with its settings and measured cost."""
MAX_DIVIDER: Final[int] = 10
"""Largest divider N a bridge takes (100 Hz control on a 1 kHz board)."""


def control_divider(
    rate_hz: object, tick_hz: int = BOARD_TICK_HZ, rates: tuple[int, ...] = CONTROL_RATES_HZ
) -> int:
    """N = ``tick_hz`` / ``rate_hz``, the board ticks per control period.

    Raises:
        ValueError: ``rate_hz`` not one of ``rates`` (the message says which are and why).
    """
    if (
        isinstance(rate_hz, (int, float))
        and not isinstance(rate_hz, bool)
        and math.isfinite(rate_hz)
        and rate_hz in rates
        and tick_hz % int(rate_hz) == 0
    ):
        return tick_hz // int(rate_hz)
    choices = ", ".join(str(rate) for rate in rates)
    raise ValueError(
        f"control rate must be one of {choices} Hz (the board's {tick_hz} Hz tick divided by a whole "
        f"number of ticks, with settings of their own), got {rate_hz!r}"
    )


def is_control_tick(board_tick: int, divider: int) -> bool:
    """True if the controller answers the feedback of ``board_tick`` (the board's own tick counter)."""
    return board_tick % divider == 0


def held_ticks(divider: int) -> int:
    """Ticks a command must outlast at 1 kHz-equivalent margin: the extra hold of a period of N ticks.

    An on-time command answering control tick c is latched by tick c + N and replaced by the next one by
    tick c + 2N: it is applied up to 2N - 1 ticks after the measurement it answers, 1 at N = 1. A
    configured validity (counted at N = 1) grows by the difference, 2 (N - 1) ticks.
    """
    return 2 * (divider - 1)


def in_flight_ticks(divider: int) -> int:
    """The extra ticks an on-time answer may be in flight at a period of N ticks: N - 1."""
    return divider - 1
