"""Frame transports behind one interface: UDP datagrams and a COBS-framed serial line. No ROS.

``LinkConfig`` (the bridge's ``link.*``) names the device (:mod:`smm_hw_bridge.device`); the frame
protocol's devices (:mod:`smm_hw_bridge.frame_device`) open one of these. A transport moves whole
frames (bytes) and knows nothing of their content; :mod:`smm_hw_bridge.protocol` parses them. Both count
what they drop before the parser sees it (foreign source, broken framing).
"""

from __future__ import annotations

import abc
import ipaddress
import select
import socket
import struct
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Final

from smm_schema.ranges import bounds, check_bounds

from smm_hw_bridge.device import DeviceName, device_names

__all__ = [
    "MAX_FRAME",
    "LinkConfig",
    "SerialTransport",
    "Transport",
    "TransportError",
    "UdpTransport",
    "cobs_decode",
    "cobs_encode",
]

MAX_FRAME: Final[int] = 512
"""Largest frame a transport passes on (bytes); longer datagrams or serial packets are dropped."""
_SO_TIMESTAMPNS: Final[int] = getattr(socket, "SO_TIMESTAMPNS", 35)
"""Linux's SO_TIMESTAMPNS (also the control message's type); Python does not name it."""
_TIMESPEC: Final[struct.Struct] = struct.Struct("@ll")


class TransportError(OSError):
    """The link cannot be opened or used (bad address, port in use, device gone)."""


class Transport(abc.ABC):
    """Moves whole frames to and from the other side of one link."""

    def __init__(self) -> None:
        self.dropped: dict[str, int] = {}
        self.last_stamp_ns: int | None = None
        """Kernel arrival time (CLOCK_REALTIME, ns) of the last frame returned; None where not known."""

    def _drop(self, why: str) -> None:
        self.dropped[why] = self.dropped.get(why, 0) + 1

    @abc.abstractmethod
    def send(self, frame: bytes) -> None:
        """Sends one frame to the peer."""

    @abc.abstractmethod
    def receive(self, timeout_s: float = 0.0) -> bytes | None:
        """Returns the next frame from the peer, waiting up to ``timeout_s`` (0 = poll), or None."""

    @abc.abstractmethod
    def fileno(self) -> int:
        """Descriptor to wait on with select()."""

    @abc.abstractmethod
    def close(self) -> None:
        """Releases the link (idempotent)."""

    def __enter__(self) -> Transport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _endpoint(name: str, address: tuple[str, int]) -> tuple[str, int]:
    if not isinstance(address, tuple) or len(address) != 2:
        raise TransportError(f"{name} must be (host, port), got {address!r}")
    host, port = address
    try:
        ip = str(ipaddress.IPv4Address(host))
    except (ipaddress.AddressValueError, ValueError) as error:
        raise TransportError(f"{name} host must be an IPv4 address, got {host!r}") from error
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise TransportError(f"{name} port must be an int in [0, 65535], got {port!r}")
    return ip, port


class UdpTransport(Transport):
    """UDP bound to ``local``; sends to ``peer`` and accepts datagrams from ``peer`` only.

    Args:
        local: (IPv4 address, port) to bind; port 0 picks a free one (see :attr:`local_address`).
        peer: (IPv4 address, port) of the other side; datagrams from anywhere else are dropped and
            counted as ``dropped["source"]``.
        kernel_timestamps: Ask the kernel for each datagram's arrival time (Linux; see
            :attr:`last_stamp_ns`).
    """

    def __init__(
        self, local: tuple[str, int], peer: tuple[str, int], *, kernel_timestamps: bool = False
    ) -> None:
        super().__init__()
        self._local = _endpoint("local", local)
        self._peer = _endpoint("peer", peer)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind(self._local)
        except OSError as error:
            self._sock.close()
            raise TransportError(f"cannot bind UDP {self._local[0]}:{self._local[1]}: {error}") from error
        self._sock.setblocking(False)
        self._stamped = False
        if kernel_timestamps and sys.platform.startswith("linux"):
            try:
                self._sock.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
                self._stamped = True
            except OSError:
                pass  # last_stamp_ns stays None

    @property
    def local_address(self) -> tuple[str, int]:
        """The bound (address, port)."""
        host, port = self._sock.getsockname()[:2]
        return str(host), int(port)

    @property
    def peer(self) -> tuple[str, int]:
        """The only (address, port) frames are accepted from and sent to."""
        return self._peer

    def set_peer(self, peer: tuple[str, int]) -> None:
        """Changes the peer (e.g. once a test knows the port the other side bound)."""
        self._peer = _endpoint("peer", peer)

    def send(self, frame: bytes) -> None:
        """Sends one datagram; a full buffer or an unreachable peer is counted, not raised."""
        try:
            self._sock.sendto(frame, self._peer)
        except (BlockingIOError, ConnectionRefusedError):
            self._drop("send")
        except OSError as error:
            raise TransportError(f"UDP send to {self._peer}: {error}") from error

    def receive(self, timeout_s: float = 0.0) -> bytes | None:
        """Next datagram from the peer; others (foreign source, oversize) are counted and skipped."""
        deadline = time.monotonic() + max(timeout_s, 0.0)
        while True:
            try:
                if self._stamped:
                    data, source = self._receive_stamped()
                else:
                    data, source = self._sock.recvfrom(MAX_FRAME + 1)
            except BlockingIOError:
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    return None
                select.select([self._sock], [], [], remaining)
                continue
            except ConnectionRefusedError:
                continue  # ICMP port unreachable from an earlier send: not a frame
            if (str(source[0]), int(source[1])) != self._peer:
                self._drop("source")
                continue
            if len(data) > MAX_FRAME:
                self._drop("oversize")
                continue
            return data

    def _receive_stamped(self) -> tuple[bytes, Any]:
        data, ancillary, _flags, source = self._sock.recvmsg(MAX_FRAME + 1, socket.CMSG_SPACE(_TIMESPEC.size))
        self.last_stamp_ns = None
        for level, kind, payload in ancillary:
            if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS and len(payload) >= _TIMESPEC.size:
                seconds, nanoseconds = _TIMESPEC.unpack_from(payload)
                self.last_stamp_ns = seconds * 1_000_000_000 + nanoseconds
        return data, source

    def fileno(self) -> int:
        """The socket's descriptor."""
        return self._sock.fileno()

    def close(self) -> None:
        """Closes the socket."""
        self._sock.close()


def cobs_encode(data: bytes) -> bytes:
    """Consistent Overhead Byte Stuffing: ``data`` without any 0x00 byte (the delimiter is not added)."""
    out = bytearray()
    block = bytearray()
    for byte in data:
        if byte == 0:
            out.append(len(block) + 1)
            out += block
            block.clear()
        else:
            block.append(byte)
            if len(block) == 254:
                out.append(255)
                out += block
                block.clear()
    out.append(len(block) + 1)
    out += block
    return bytes(out)


def cobs_decode(data: bytes) -> bytes:
    """Inverse of :func:`cobs_encode`.

    Raises:
        ValueError: ``data`` is not a valid COBS packet (a 0x00 byte or a code past the end).
    """
    out = bytearray()
    index = 0
    while index < len(data):
        code = data[index]
        if code == 0:
            raise ValueError("COBS packet holds a 0x00 byte")
        end = index + code
        if end > len(data):
            raise ValueError("COBS code runs past the end of the packet")
        block = data[index + 1 : end]
        if 0 in block:
            raise ValueError("COBS packet holds a 0x00 byte")
        out += block
        index = end
        if code != 255 and index < len(data):
            out.append(0)
    return bytes(out)


class SerialTransport(Transport):
    """A serial line (pyserial) carrying COBS-encoded frames, each followed by one 0x00 delimiter.

    Args:
        port: Device name (``/dev/ttyUSB0``, a pty slave...) or an already open ``serial.Serial``-like
            object with ``read``, ``write``, ``in_waiting``, ``fileno`` and ``close``.
        baudrate: Line speed (bit/s), used when opening ``port`` by name.
    """

    def __init__(self, port: Any, baudrate: int = 921_600) -> None:
        super().__init__()
        if isinstance(port, str):
            import serial  # noqa: PLC0415 - pyserial is needed only for this transport

            try:
                self._port: Any = serial.Serial(port, baudrate=baudrate, timeout=0)
            except (serial.SerialException, ValueError) as error:
                raise TransportError(f"cannot open serial port {port!r}: {error}") from error
        else:
            self._port = port
        self._buffer = bytearray()
        self._frames: deque[bytes] = deque()
        self._overflowing = False

    def send(self, frame: bytes) -> None:
        """Writes the COBS packet and its delimiter."""
        try:
            self._port.write(cobs_encode(frame) + b"\x00")
        except OSError as error:
            raise TransportError(f"serial write: {error}") from error

    def _feed(self, chunk: bytes) -> None:
        for byte in chunk:
            if byte != 0:
                if len(self._buffer) > 2 * MAX_FRAME:
                    self._overflowing = True  # runaway packet: drop it at its delimiter
                    self._buffer.clear()
                self._buffer.append(byte)
                continue
            if self._overflowing:
                self._drop("oversize")
                self._overflowing = False
            elif self._buffer:
                try:
                    frame = cobs_decode(bytes(self._buffer))
                except ValueError:
                    self._drop("framing")
                else:
                    if len(frame) > MAX_FRAME:
                        self._drop("oversize")
                    else:
                        self._frames.append(frame)
            self._buffer.clear()

    def receive(self, timeout_s: float = 0.0) -> bytes | None:
        """Next complete frame; broken COBS packets are counted as ``dropped["framing"]``."""
        deadline = time.monotonic() + max(timeout_s, 0.0)
        while not self._frames:
            try:
                waiting = self._port.in_waiting
                chunk = self._port.read(waiting or 1) if waiting else b""
            except OSError as error:
                raise TransportError(f"serial read: {error}") from error
            if chunk:
                self._feed(bytes(chunk))
                continue
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return None
            select.select([self._port.fileno()], [], [], remaining)
        return self._frames.popleft()

    def fileno(self) -> int:
        """The port's descriptor."""
        return int(self._port.fileno())

    def close(self) -> None:
        """Closes the port."""
        self._port.close()


@dataclass(frozen=True)
class LinkConfig:
    """How the bridge reaches the board (read at ``configure``).

    Attributes:
        transport: The device, a row of ``smm_hw_bridge.device.DEVICES``: "udp" or "serial" (the frame
            protocol over UDP or a serial line), "canopen" (CiA 408 valves and CiA 406 encoders).
        bind_address: UDP: IPv4 address the bridge binds (default loopback).
        bind_port: UDP: port the bridge binds (0 = any free one).
        board_address: UDP: the board's IPv4 address; frames from anywhere else are dropped.
        board_port: UDP: the board's port.
        serial_port: Serial: device name.
        baudrate: Serial: line speed (bit/s).
        configure_timeout: Time ``configure`` waits for a valid feedback frame (s).
    """

    transport: DeviceName = "udp"
    bind_address: str = "127.0.0.1"
    bind_port: int = field(default=50100, metadata=bounds(0, 65535))
    board_address: str = "127.0.0.1"
    board_port: int = field(default=50101, metadata=bounds(1, 65535))
    serial_port: str = ""
    baudrate: int = field(default=921_600, metadata=bounds(1, 100_000_000))
    configure_timeout: float = field(default=2.0, metadata=bounds(0.001, 600.0))

    def __post_init__(self) -> None:
        if self.transport not in device_names():
            raise ValueError(f"transport must be one of {device_names()}, got {self.transport!r}")
        for name in ("bind_address", "board_address"):
            try:
                ipaddress.IPv4Address(getattr(self, name))
            except ValueError as error:
                raise ValueError(f"{name} must be an IPv4 address, got {getattr(self, name)!r}") from error
        check_bounds(self)
        if self.transport == "serial" and not self.serial_port:
            raise ValueError("serial_port must name a device when transport is 'serial'")
