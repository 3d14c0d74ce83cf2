"""How the bridge's receiving thread waits for the next reading: the direct loop's polling. Pure, no ROS."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final

from smm_schema.ranges import bounds

from smm_hw_bridge.control_rate import is_control_tick
from smm_hw_bridge.core import BridgeCore
from smm_hw_bridge.device import Device, Reading

__all__ = ["LINK_CHECK_S", "LoopSettings", "next_reading"]

LINK_CHECK_S: Final[float] = 0.005
"""Period of the link and host-watchdog check, done by the receiving thread (s)."""
DEFAULT_SWITCH_INTERVAL: Final[float] = 0.0005
"""Default ``sys.setswitchinterval`` of the direct loop's process (s); docs/LAUNCH.md says why."""
DEFAULT_SPIN_US: Final[int] = 150
"""Default ``loop.spin_us`` (us); docs/LAUNCH.md says why."""


@dataclass(frozen=True)
class LoopSettings:
    """The direct loop's own settings (``loop.*`` of a bridge with an answerer, read-only).

    Attributes:
        switch_interval: ``sys.setswitchinterval`` of the process (s): the longest a thread holding the GIL
            keeps the reader thread waiting once a frame arrived, in [1e-5, 0.1].
        spin_us: The reader polls for the next frame from this long before it is due (one board period
            after the last) until as long after, instead of sleeping (us), in [0, 100000]; 0 = always
            sleep. Saves the wake-up from idle at the cost of that CPU time per period.
    """

    switch_interval: float = field(default=DEFAULT_SWITCH_INTERVAL, metadata=bounds(1e-5, 0.1))
    spin_us: int = field(default=DEFAULT_SPIN_US, metadata=bounds(0, 100_000))

    def __post_init__(self) -> None:
        value = self.switch_interval
        if isinstance(value, bool) or not isinstance(value, float) or not 1e-5 <= value <= 0.1:
            raise ValueError(f"switch_interval must be a number of seconds in [1e-5, 0.1], got {value!r}")
        spin = self.spin_us
        if isinstance(spin, bool) or not isinstance(spin, int) or not 0 <= spin <= 100_000:
            raise ValueError(f"spin_us must be an int in [0, 100000] (us), got {spin!r}")


def next_reading(
    device: Device, core: BridgeCore | None, last_rx_ns: int | None, spin_us: int, clock: Callable[[], int]
) -> Reading | None:
    """The next reading of ``device``, None if nothing came.

    With ``spin_us`` > 0: a wait until ``spin_us`` before it is due (one board period after
    ``last_rx_ns``), then polls until as long after; else (or when the board holds through the next tick)
    one wait of :data:`LINK_CHECK_S`.
    """
    reading = None
    spin_ns = spin_us * 1000
    feedback = None if core is None else core.last_feedback
    if (
        core is not None
        and feedback is not None
        and not is_control_tick(feedback.tick + 1, core.config.control_divider)
    ):
        spin_ns = 0  # the next frame is one the board holds through: nothing to answer in a hurry
    if spin_ns and last_rx_ns is not None and core is not None:
        due = last_rx_ns + core.config.period_ns
        now = clock()
        if now < due - spin_ns:
            reading = device.read((due - spin_ns - now) / 1e9)
        while reading is None and clock() < due + spin_ns:
            reading = device.read(0.0)
    if reading is None:
        reading = device.read(LINK_CHECK_S)
    return reading
