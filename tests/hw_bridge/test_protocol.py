"""Frame layout, round trips and the parser's one error type (hypothesis: random and mutated frames)."""

from __future__ import annotations

import struct
import zlib

import pytest

from smm_hw_bridge import protocol as p

COMMAND = p.CommandFrame(
    session=0x11223344,
    seq=7,
    board_session=0xA5A5A5A5,
    answers_seq=6,
    answers_tick=1006,
    flags=int(p.CommandFlag.ENABLE),
    validity=20,
    codes=(1234, -32767),
)
FEEDBACK = p.FeedbackFrame(
    session=0xA5A5A5A5,
    seq=9,
    tick=1009,
    host_session=0x11223344,
    counts=(5, 0xFFFFFFFF),
    adc=(2048, 0, 1, 4095),
    status=int(p.StatusBit.ENABLED),
    faults=int(p.FaultBit.SUPPLY_LOW),
    applied_seq=7,
    applied_age=3,
    output_codes=(1200, -32767),
    late_commands=1,
    crc_errors=2,
    dropped_frames=3,
)


def test_sizes_and_header_bytes_follow_the_documented_layout() -> None:
    data = p.encode(COMMAND)
    assert (p.COMMAND_SIZE, p.FEEDBACK_SIZE, p.HEADER_SIZE) == (40, 72, 16)
    assert data[:4] == b"SMMB" and data[4] == 1 and data[5] == 1
    assert struct.unpack_from("<H", data, 6)[0] == 40
    assert struct.unpack_from("<II", data, 8) == (0x11223344, 7)
    # command body at the offsets of docs/HW_PROTOCOL.md
    assert struct.unpack_from("<IIIHHhh", data, 16) == (0xA5A5A5A5, 6, 1006, 1, 20, 1234, -32767)
    assert struct.unpack_from("<I", data, 36)[0] == zlib.crc32(data[:36])
    fb = p.encode(FEEDBACK)
    assert fb[5] == 2 and len(fb) == 72
    assert struct.unpack_from("<II", fb, 16) == (1009, 0x11223344)
    assert struct.unpack_from("<II", fb, 24) == (5, 0xFFFFFFFF)
    assert struct.unpack_from("<4H", fb, 32) == (2048, 0, 1, 4095)
    assert struct.unpack_from("<HHIHhhH", fb, 40) == (1, 1, 7, 3, 1200, -32767, 0)
    assert struct.unpack_from("<III", fb, 56) == (1, 2, 3)


def test_crc_is_the_ieee_crc32_check_value() -> None:
    # CRC-32/ISO-HDLC check value of "123456789": what a DSP implementation must reproduce.
    assert zlib.crc32(b"123456789") == 0xCBF43926


@pytest.mark.parametrize("frame", [COMMAND, FEEDBACK])
def test_round_trip(frame: p.CommandFrame | p.FeedbackFrame) -> None:
    assert p.decode(p.encode(frame)) == frame


def _reframe(data: bytes) -> bytes:
    """Recomputes the CRC so a check after it is reached."""
    return data[:-4] + struct.pack("<I", zlib.crc32(data[:-4]))


@pytest.mark.parametrize(
    ("mutate", "reason"),
    [
        (lambda d: d[:10], p.Reason.LENGTH),
        (lambda d: b"XMMB" + d[4:], p.Reason.MAGIC),
        (lambda d: d + b"\x00", p.Reason.LENGTH),
        (lambda d: d[:20] + bytes([d[20] ^ 1]) + d[21:], p.Reason.CRC),
        (lambda d: _reframe(d[:4] + b"\x02" + d[5:]), p.Reason.VERSION),
        (lambda d: _reframe(d[:5] + b"\x07" + d[6:]), p.Reason.TYPE),
        (lambda d: _reframe(d[:5] + b"\x02" + d[6:]), p.Reason.LENGTH),  # feedback type, command length
        (lambda d: _reframe(d[:28] + struct.pack("<H", 0x0100) + d[30:]), p.Reason.FIELD),  # undefined flag
        (lambda d: _reframe(d[:32] + struct.pack("<h", -32768) + d[34:]), p.Reason.FIELD),
        (lambda d: _reframe(d[:8] + b"\x00\x00\x00\x00" + d[12:]), p.Reason.FIELD),  # session 0
    ],
)
def test_each_rejection_has_its_reason(mutate, reason: p.Reason) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(p.ProtocolError) as caught:
        p.decode(mutate(p.encode(COMMAND)))
    assert caught.value.reason is reason


def test_feedback_adc_out_of_12_bits_and_reserved_field_are_rejected() -> None:
    data = p.encode(FEEDBACK)
    for offset, value in ((32, 4096), (54, 1)):
        bad = _reframe(data[:offset] + struct.pack("<H", value) + data[offset + 2 :])
        with pytest.raises(p.ProtocolError) as caught:
            p.decode(bad)
        assert caught.value.reason is p.Reason.FIELD


def test_typed_decoders_refuse_the_other_type() -> None:
    with pytest.raises(p.ProtocolError):
        p.decode_command(p.encode(FEEDBACK))
    with pytest.raises(p.ProtocolError):
        p.decode_feedback(p.encode(COMMAND))
    assert p.decode_command(p.encode(COMMAND)) == COMMAND


def test_constructing_an_invalid_frame_is_refused_before_it_is_sent() -> None:
    with pytest.raises(p.ProtocolError):
        p.CommandFrame(1, 0, 0, 0, 0, 0, 0, (40000, 0))
    with pytest.raises(p.ProtocolError):
        p.CommandFrame(1, -1, 0, 0, 0, 0, 0, (0, 0))
    with pytest.raises(p.ProtocolError):
        p.CommandFrame(1, 0, 0, 0, 0, 0, 1 << 16, (0, 0))


def test_serial_number_arithmetic_across_the_wrap() -> None:
    assert p.seq_newer(0, 0xFFFFFFFF)
    assert not p.seq_newer(0xFFFFFFFF, 0)
    assert p.u32_diff(3, 0xFFFFFFFE) == 5
    assert p.u32_diff(5, 5) == 0


def test_non_bytes_input_is_the_typed_error() -> None:
    with pytest.raises(p.ProtocolError):
        p.decode(12345)  # type: ignore[arg-type]
