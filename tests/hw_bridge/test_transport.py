"""UDP and serial (COBS over a pseudo-terminal pair) transports behind one interface."""

from __future__ import annotations

import os
import socket
import tty

import pytest
import serial
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_hw_bridge.transport import (
    SerialTransport,
    Transport,
    TransportError,
    UdpTransport,
    cobs_decode,
    cobs_encode,
)

LOOPBACK = "127.0.0.1"


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=700))
def test_cobs_round_trip_has_no_zero_byte(data: bytes) -> None:
    encoded = cobs_encode(data)
    assert 0 not in encoded
    assert cobs_decode(encoded) == data
    assert len(encoded) <= len(data) + len(data) // 254 + 1


def test_cobs_known_vectors() -> None:
    # Vectors of the COBS paper (Cheshire and Baker, 1999) / Wikipedia.
    assert cobs_encode(b"\x00") == b"\x01\x01"
    assert cobs_encode(b"\x00\x00") == b"\x01\x01\x01"
    assert cobs_encode(b"\x11\x22\x00\x33") == b"\x03\x11\x22\x02\x33"
    assert cobs_encode(bytes(range(1, 255))) == b"\xff" + bytes(range(1, 255)) + b"\x01"
    with pytest.raises(ValueError):
        cobs_decode(b"\x05\x11")


def _udp_pair() -> tuple[UdpTransport, UdpTransport]:
    a = UdpTransport((LOOPBACK, 0), (LOOPBACK, 9))
    b = UdpTransport((LOOPBACK, 0), a.local_address)
    a.set_peer(b.local_address)
    return a, b


def test_udp_moves_frames_both_ways() -> None:
    a, b = _udp_pair()
    with a, b:
        a.send(b"hello")
        assert b.receive(2.0) == b"hello"
        b.send(b"back")
        assert a.receive(2.0) == b"back"
        assert a.receive(0.0) is None


def test_udp_kernel_timestamps_give_the_arrival_not_the_read() -> None:
    """The stamp is taken when the datagram reaches the socket, however late the receiver reads it."""
    import time

    a = UdpTransport((LOOPBACK, 0), (LOOPBACK, 9), kernel_timestamps=True)
    b = UdpTransport((LOOPBACK, 0), a.local_address)
    a.set_peer(b.local_address)
    with a, b:
        # Linux turns arrival stamping on from a work queue: until then a datagram is stamped when read.
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            before = time.time_ns()
            b.send(b"warm-up")
            after = time.time_ns()
            time.sleep(0.02)
            assert a.receive(2.0) == b"warm-up"
            if a.last_stamp_ns is not None and a.last_stamp_ns <= after:
                break
        stamps = []
        for payload in (b"one", b"two"):
            before = time.time_ns()
            b.send(payload)
            after = time.time_ns()
            time.sleep(0.02)  # the reader is late
            read = time.time_ns()
            assert a.receive(2.0) == payload
            assert a.last_stamp_ns is not None
            assert before <= a.last_stamp_ns <= after < read
            stamps.append(a.last_stamp_ns)
        assert stamps[0] < stamps[1]
        a.send(b"back")
        assert b.receive(2.0) == b"back"
        assert b.last_stamp_ns is None  # b asked for none


def test_udp_accepts_frames_only_from_the_configured_peer() -> None:
    a, b = _udp_pair()
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    with a, b, stranger:
        stranger.bind((LOOPBACK, 0))
        stranger.sendto(b"intruder", a.local_address)
        b.send(b"genuine")
        assert a.receive(2.0) == b"genuine"
        assert a.receive(0.05) is None
        assert a.dropped == {"source": 1}


def test_udp_binds_to_the_configured_address_and_rejects_bad_ones() -> None:
    with UdpTransport((LOOPBACK, 0), (LOOPBACK, 9)) as t:
        assert t.local_address[0] == LOOPBACK
    for local in [("localhost", 0), ("127.0.0.1", 70000), ("127.0.0.1",)]:
        with pytest.raises(TransportError):
            UdpTransport(local, (LOOPBACK, 9))  # type: ignore[arg-type]
    with UdpTransport((LOOPBACK, 0), (LOOPBACK, 9)) as held, pytest.raises(TransportError):
        UdpTransport(held.local_address, (LOOPBACK, 9))


def _pty_pair() -> tuple[SerialTransport, SerialTransport]:
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    slave_name = os.ttyname(slave)
    host = SerialTransport(slave_name)  # pyserial opens the slave by its device name
    os.close(slave)

    class MasterEnd:
        """The pty master as a minimal serial port."""

        def __init__(self, fd: int) -> None:
            self.fd = fd
            os.set_blocking(fd, False)

        @property
        def in_waiting(self) -> int:
            return 1

        def read(self, n: int) -> bytes:
            try:
                return os.read(self.fd, max(n, 1))
            except BlockingIOError:
                return b""

        def write(self, data: bytes) -> int:
            return os.write(self.fd, data)

        def fileno(self) -> int:
            return self.fd

        def close(self) -> None:
            os.close(self.fd)

    return host, SerialTransport(MasterEnd(master))


def test_serial_frames_cross_a_pseudo_terminal_pair() -> None:
    host, board = _pty_pair()
    with host, board:
        frames = [b"\x00\x01\x00", bytes(range(256)) * 2, b"SMMB"]
        for frame in frames:
            host.send(frame)
        assert [board.receive(2.0) for _ in frames] == frames
        board.send(b"reply\x00")
        assert host.receive(2.0) == b"reply\x00"
        assert host.receive(0.0) is None


def test_serial_broken_packets_are_counted_and_the_stream_resynchronises() -> None:
    host, board = _pty_pair()
    with host, board:
        raw = board._port  # write garbage on the line directly
        raw.write(b"\x07\x11\x00")  # COBS code past the end of its packet
        raw.write(b"\x01" * 2000 + b"\x00")  # runaway packet, longer than any frame
        board.send(b"after")
        assert host.receive(2.0) == b"after"
        assert host.dropped == {"framing": 1, "oversize": 1}


def test_both_transports_share_the_interface() -> None:
    assert issubclass(UdpTransport, Transport) and issubclass(SerialTransport, Transport)
    with pytest.raises(TransportError):
        SerialTransport("/dev/does-not-exist-smm")
    assert serial.VERSION.startswith("3.")
