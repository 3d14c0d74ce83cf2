"""The I/O device the bridge's loop runs over: open, read feedback, write a valve command, make safe. No ROS.

ros2_control's hardware component: the loop (:mod:`smm_hw_bridge.loop`) calls :meth:`Device.read` and
:meth:`Device.write`; what each field means for a device and how to add one: docs/DESIGN.md, "The bridge's
loop and its devices". A device is one module and one row of :data:`DEVICES`; ``link.transport`` names it.
"""

from __future__ import annotations

import abc
import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final, Literal, Protocol, TypeAlias

from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.core import BridgeConfig
from smm_hw_bridge.protocol import CommandFrame, FeedbackFrame, Reason

__all__ = [
    "DEVICES",
    "Device",
    "DeviceDescription",
    "DeviceError",
    "DeviceName",
    "Feedback",
    "Link",
    "Reading",
    "ValveCommand",
    "open_device",
]

Feedback: TypeAlias = FeedbackFrame
"""One feedback of a device: joint positions in its units (``counts``), its time stamp (``tick``), its
sequence counter (``seq``) and its health (``session``: boot / node state, ``host_session``: the host it
obeys, ``status`` and ``faults`` bits, ``adc``: supply and other analog values, ``output_codes`` applied)."""
ValveCommand: TypeAlias = CommandFrame
"""One valve command: D/A ``codes``, ``flags`` (enable, e-stop, re-arm), the feedback it answers
(``answers_seq``, ``answers_tick``) and its ``validity`` (ticks); sessions and ``seq`` for devices that check
them."""
Reading: TypeAlias = Feedback | Reason
"""What :meth:`Device.read` gives: a feedback, or why what arrived is not one (counted by the loop)."""


class DeviceError(OSError):
    """The device cannot be opened or used (bad address, port in use, device gone)."""


@dataclass(frozen=True)
class DeviceDescription:
    """What a device offers.

    Attributes:
        name: Its name in :data:`DEVICES` (``link.transport``).
        joints: Position channels, in joint order.
        valves: Valve (D/A) channels, in joint order.
        analog: Analog channels of the feedback, in order (channel 0: supply pressure).
        own_watchdog: The device nulls its valves by itself when commands stop.
        validity: Commands carry how long they may be applied (ticks), checked by the device.
    """

    name: str
    joints: tuple[str, ...]
    valves: tuple[str, ...]
    analog: tuple[str, ...]
    own_watchdog: bool
    validity: bool


class Device(abc.ABC):
    """A bench's encoders and valves behind read / write (one per configured session)."""

    description: DeviceDescription

    def __init__(self) -> None:
        self.dropped: dict[str, int] = {}
        """What the device dropped before the loop saw it, by reason (foreign source, broken framing)."""
        self.found: tuple[str, ...] = ()
        """What :meth:`open` found (a CANopen bench: each node, its device type and identity), for the log."""
        self.faults: list[str] = []
        """The faults it saw, in words (a CANopen bench: each naming the node and the code), for the log."""

    @abc.abstractmethod
    def open(self) -> None:
        """Acquires the link (idempotent).

        Raises:
            DeviceError: It cannot be opened.
        """

    @abc.abstractmethod
    def close(self) -> None:
        """Releases the link (idempotent)."""

    @abc.abstractmethod
    def read(self, timeout_s: float) -> Reading | None:
        """The next feedback, or why what arrived is refused; None after ``timeout_s`` (0: poll) without any.

        Raises:
            DeviceError: The link failed.
        """

    @abc.abstractmethod
    def write(self, command: ValveCommand) -> None:
        """Sends one valve command (a full buffer is counted in :attr:`dropped`, not raised).

        Raises:
            DeviceError: The link failed.
        """

    @abc.abstractmethod
    def make_safe(self) -> str | None:
        """Nulls or disables the valves by the device's own means, after the loop's last safe command.

        Returns None, or what it could not do in one line for the log (a valve not told, and what stops it).
        """


DEVICES: Final[Mapping[str, str]] = {
    "udp": "smm_hw_bridge.frame_device:udp_device",
    "serial": "smm_hw_bridge.frame_device:serial_device",
    "canopen": "smm_hw_bridge.canopen_device:canopen_device",
}
"""Every device: ``link.transport`` name -> ``module:factory`` (the factory takes the ``LinkConfig``, the
``CanopenConfig`` and the ``BridgeConfig``: the bridge's ``link.*``, ``canopen.*`` and ``bridge.*``)."""
if TYPE_CHECKING:
    DeviceName: TypeAlias = str
else:
    DeviceName = Literal[tuple(DEVICES)]
    """The type of ``link.transport``: the names of :data:`DEVICES` (the parameter's choices)."""


def device_names() -> tuple[str, ...]:
    """The names ``link.transport`` takes."""
    return tuple(DEVICES)


class Link(Protocol):
    """What names a device: ``LinkConfig`` (:mod:`smm_hw_bridge.transport`), the bridge's ``link.*``."""

    @property
    def transport(self) -> str:
        """The device's name in :data:`DEVICES`."""


def open_device(link: Link, canopen: CanopenConfig, bridge: BridgeConfig) -> Device:
    """The device ``link.transport`` names, opened; its factory is given ``link``, ``canopen``, ``bridge``.

    Raises:
        DeviceError: It cannot be opened.
    """
    module, _, factory = DEVICES[link.transport].partition(":")
    device: Device = getattr(importlib.import_module(module), factory)(link, canopen, bridge)
    device.open()
    return device
