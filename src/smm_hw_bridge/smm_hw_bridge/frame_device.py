"""This project's frame protocol (docs/HW_PROTOCOL.md) over a :class:`Transport`: one :class:`Device`. No ROS.

Framing, CRC and field checks are :mod:`smm_hw_bridge.protocol`'s; sessions, sequence numbers, heartbeats
(every feedback answered) and the board's validity watchdog are the board's and the loop's, unchanged.
"""

from __future__ import annotations

from collections.abc import Callable

from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.core import BridgeConfig
from smm_hw_bridge.device import Device, DeviceDescription, DeviceError, Reading, ValveCommand
from smm_hw_bridge.protocol import ADC_CHANNELS, ProtocolError, decode_feedback, encode
from smm_hw_bridge.transport import LinkConfig, SerialTransport, Transport, TransportError, UdpTransport

__all__ = ["FrameDevice", "serial_device", "udp_device"]


def _description(name: str) -> DeviceDescription:
    return DeviceDescription(
        name=name,
        joints=("alpha", "beta"),
        valves=("alpha", "beta"),
        analog=("supply", *(f"spare{index}" for index in range(1, ADC_CHANNELS))),
        own_watchdog=True,
        validity=True,
    )


class FrameDevice(Device):
    """The I/O board speaking the frame protocol over the transport ``opener`` gives.

    Args:
        name: The device's name in :data:`~smm_hw_bridge.device.DEVICES`.
        opener: Opens the transport (at :meth:`open`); raises ``TransportError``.
    """

    def __init__(self, name: str, opener: Callable[[], Transport]) -> None:
        super().__init__()
        self.description = _description(name)
        self._opener = opener
        self.transport: Transport | None = None
        """The open transport (None before :meth:`open` and after :meth:`close`)."""

    def open(self) -> None:
        """Opens the transport."""
        if self.transport is None:
            try:
                self.transport = self._opener()
            except TransportError as error:
                raise DeviceError(str(error)) from error
            self.dropped = self.transport.dropped

    def close(self) -> None:
        """Closes the transport."""
        transport, self.transport = self.transport, None
        if transport is not None:
            transport.close()

    def read(self, timeout_s: float) -> Reading | None:
        """The next frame decoded, or the reason the parser refused it."""
        transport = self.transport
        if transport is None:
            raise DeviceError("the device is not open")
        try:
            data = transport.receive(timeout_s)
        except TransportError as error:
            raise DeviceError(str(error)) from error
        if data is None:
            return None
        try:
            return decode_feedback(data)
        except ProtocolError as error:
            return error.reason

    def write(self, command: ValveCommand) -> None:
        """Encodes and sends one command frame."""
        transport = self.transport
        if transport is None:
            raise DeviceError("the device is not open")
        try:
            transport.send(encode(command))
        except TransportError as error:
            raise DeviceError(str(error)) from error

    def make_safe(self) -> None:
        """Nothing beyond the loop's safe frame: the board nulls by itself ``validity`` ticks later."""


def udp_device(link: LinkConfig, canopen: CanopenConfig, bridge: BridgeConfig) -> FrameDevice:
    """The board over UDP (``link.bind_*``, ``link.board_*``)."""
    return FrameDevice(
        "udp",
        lambda: UdpTransport((link.bind_address, link.bind_port), (link.board_address, link.board_port)),
    )


def serial_device(link: LinkConfig, canopen: CanopenConfig, bridge: BridgeConfig) -> FrameDevice:
    """The board over a COBS-framed serial line (``link.serial_port``, ``link.baudrate``)."""
    return FrameDevice("serial", lambda: SerialTransport(link.serial_port, link.baudrate))
