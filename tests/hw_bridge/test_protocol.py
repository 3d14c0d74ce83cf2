"""Frame layout, round trips and the parser's one error type (hypothesis: random and mutated frames)."""

from __future__ import annotations

import dataclasses
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


def _command_bytes(
    *,
    magic: int = 0x424D4D53,
    version: int = 1,
    frame_type: int = 1,
    length: int = 40,
    session: int = 0x11223344,
    flags: int = 1,
    codes: tuple[int, int] = (1234, -32767),
    size: int = 40,
    crc: int | None = None,
) -> bytes:
    """A command frame built by hand from docs/HW_PROTOCOL.md sections 2, 3 and 5 (not with the encoder)."""
    body = struct.pack("<IBBHII", magic, version, frame_type, length, session, 7)
    body += struct.pack("<IIIHHhh", 0xA5A5A5A5, 6, 1006, flags, 20, *codes)
    body = (body + bytes(max(size - 4 - len(body), 0)))[: size - 4]
    return body + struct.pack("<I", zlib.crc32(body) if crc is None else crc)


def _feedback_bytes(**fields: int) -> bytes:
    """The feedback frame FEEDBACK built by hand (section 4), with some u16/u32 fields replaced."""
    values = {
        "tick": 1009,
        "host_session": 0x11223344,
        "status": 1,
        "faults": 1,
        "applied_seq": 7,
        "applied_age": 3,
        "reserved": 0,
        "adc0": 2048,
    } | fields
    body = struct.pack("<IBBHII", 0x424D4D53, 1, 2, 72, 0xA5A5A5A5, 9)
    body += struct.pack("<IIII", values["tick"], values["host_session"], 5, 0xFFFFFFFF)
    body += struct.pack("<4H", values["adc0"], 0, 1, 4095)
    body += struct.pack(
        "<HHIH", values["status"], values["faults"], values["applied_seq"], values["applied_age"]
    )
    body += struct.pack("<hhH", 1200, -32767, values["reserved"])
    body += struct.pack("<III", 1, 2, 3)
    return body + struct.pack("<I", zlib.crc32(body))


def _reason(data: bytes | bytearray | memoryview) -> tuple[p.Reason, str]:
    with pytest.raises(p.ProtocolError) as caught:
        p.decode(data)
    return caught.value.reason, str(caught.value)


def test_hand_built_frames_decode_and_the_encoder_builds_the_same_bytes() -> None:
    assert p.decode(_command_bytes()) == COMMAND
    assert p.encode(COMMAND) == _command_bytes()
    assert p.decode(_feedback_bytes()) == FEEDBACK
    assert p.encode(FEEDBACK) == _feedback_bytes()
    for buffer in (bytearray(_command_bytes()), memoryview(_feedback_bytes())):
        assert p.decode(buffer) in (COMMAND, FEEDBACK)


_GOOD_CRC_V2 = zlib.crc32(_command_bytes(version=2)[:36])
#: Frames that break one or two checks of section 6 (the first one found is reported), with the full text.
PARSING_ORDER = [
    (_command_bytes()[:19], p.Reason.LENGTH, "length: 19 bytes is shorter than header + CRC"),
    (b"", p.Reason.LENGTH, "length: 0 bytes is shorter than header + CRC"),
    (
        _command_bytes(magic=0, size=20, length=40),
        p.Reason.MAGIC,
        "magic: magic 0x00000000, expected 0x424d4d53",
    ),
    (
        _command_bytes(magic=0x424D4D54, length=41),
        p.Reason.MAGIC,
        "magic: magic 0x424d4d54, expected 0x424d4d53",
    ),
    (_command_bytes(length=41, crc=0), p.Reason.LENGTH, "length: length field 41, datagram 40 bytes"),
    (
        _command_bytes(version=2, crc=_GOOD_CRC_V2 ^ 1),
        p.Reason.CRC,
        f"crc: CRC {_GOOD_CRC_V2 ^ 1:#010x}, computed {_GOOD_CRC_V2:#010x}",
    ),
    (
        _command_bytes(version=2, frame_type=9),
        p.Reason.VERSION,
        "version: protocol version 2, this side speaks 1",
    ),
    (_command_bytes(version=0), p.Reason.VERSION, "version: protocol version 0, this side speaks 1"),
    (_command_bytes(frame_type=0, session=0), p.Reason.TYPE, "type: frame type 0"),
    (_command_bytes(frame_type=3, session=0), p.Reason.TYPE, "type: frame type 3"),
    (_command_bytes(length=72, size=72), p.Reason.LENGTH, "length: COMMAND frame of 72 bytes, expected 40"),
    (
        _command_bytes(frame_type=2, session=0),
        p.Reason.LENGTH,
        "length: FEEDBACK frame of 40 bytes, expected 72",
    ),
    (_command_bytes(session=0), p.Reason.FIELD, "field: session must be != 0 (0 means no session)"),
    (_feedback_bytes(reserved=2), p.Reason.FIELD, "field: reserved field is 2, must be 0"),
    (12345, p.Reason.FIELD, "field: not a byte buffer: int"),
]


@pytest.mark.parametrize(("data", "reason", "text"), PARSING_ORDER)
def test_the_parsing_order_of_section_6_and_the_reason_texts(
    data: bytes, reason: p.Reason, text: str
) -> None:
    assert _reason(data) == (reason, text)


@pytest.mark.parametrize("bit", range(3, 16))
def test_every_undefined_command_flag_is_a_field_error(bit: int) -> None:
    assert _reason(_command_bytes(flags=1 | 1 << bit)) == (
        p.Reason.FIELD,
        f"field: flags has undefined bits set: {1 | 1 << bit:#06x}",
    )


def test_the_defined_flags_and_codes_at_their_range_ends_are_accepted() -> None:
    frame = p.decode(_command_bytes(flags=0b111, codes=(32767, -32767)))
    assert isinstance(frame, p.CommandFrame)
    assert frame.flags == int(p.CommandFlag.ENABLE | p.CommandFlag.ESTOP | p.CommandFlag.REARM)
    assert frame.codes == (32767, -32767)
    assert frame.enabled
    assert not p.decode_command(_command_bytes(flags=int(p.CommandFlag.ESTOP))).enabled
    assert _reason(_command_bytes(codes=(0, -32768))) == (
        p.Reason.FIELD,
        "field: codes must hold ints in [-32767, 32767], got (0, -32768)",
    )


@pytest.mark.parametrize(
    ("fields", "text"),
    [
        ({"status": 0x20}, "status has undefined bits set: 0x0020"),
        ({"adc0": 4096}, "adc must be an int in [0, 2**12), got 4096"),
    ],
)
def test_feedback_field_errors(fields: dict[str, int], text: str) -> None:
    assert _reason(_feedback_bytes(**fields)) == (p.Reason.FIELD, f"field: {text}")


def test_feedback_fields_at_their_range_ends_are_accepted() -> None:
    frame = p.decode_feedback(
        _feedback_bytes(status=0x1F, faults=0xFFFF, applied_age=0xFFFF, applied_seq=0xFFFFFFFF, tick=0)
    )
    assert (frame.status, frame.faults, frame.applied_age, frame.applied_seq, frame.tick) == (
        0x1F,
        0xFFFF,
        0xFFFF,
        0xFFFFFFFF,
        0,
    )


#: All-zero frames (session 1): each test changes one field with dataclasses.replace, which validates anew.
ZERO_COMMAND = p.CommandFrame(1, 0, 0, 0, 0, 0, 0, (0, 0))
ZERO_FEEDBACK = p.FeedbackFrame(1, 0, 0, 0, (0, 0), (0, 0, 0, 0), 0, 0, 0, 0, (0, 0), 0, 0, 0)


def _command(**fields: object) -> p.CommandFrame:
    return dataclasses.replace(ZERO_COMMAND, **fields)  # type: ignore[arg-type]


def _feedback(**fields: object) -> p.FeedbackFrame:
    return dataclasses.replace(ZERO_FEEDBACK, **fields)  # type: ignore[arg-type]


U32_FIELDS = ("session", "seq", "board_session", "answers_seq", "answers_tick")


@pytest.mark.parametrize("name", U32_FIELDS)
def test_command_u32_fields_are_checked_at_both_ends_and_by_type(name: str) -> None:
    assert getattr(_command(**{name: 0xFFFFFFFF}), name) == 0xFFFFFFFF
    for bad in (1 << 32, -1, True, 1.0):
        with pytest.raises(p.ProtocolError, match=rf"^field: {name} must be an int in \[0, 2\*\*32\), got"):
            _command(**{name: bad})


@pytest.mark.parametrize(("name", "bits"), [("flags", 16), ("validity", 16)])
def test_command_u16_fields(name: str, bits: int) -> None:
    with pytest.raises(p.ProtocolError, match=rf"^field: {name} must be an int in \[0, 2\*\*{bits}\)"):
        _command(**{name: 1 << bits})
    assert _command(validity=0xFFFF).validity == 0xFFFF


@pytest.mark.parametrize("codes", [(0,), (0, 0, 0), [0, 0], (True, 0), (0, 1.0), (32768, 0), (0, -32768)])
def test_command_codes_must_be_two_ints_in_range(codes: object) -> None:
    with pytest.raises(p.ProtocolError, match=r"^field: codes must "):
        _command(codes=codes)


def test_session_0_is_refused_on_both_sides() -> None:
    with pytest.raises(p.ProtocolError, match=r"^field: session must be != 0"):
        _command(session=0)
    with pytest.raises(p.ProtocolError, match=r"^field: session must be != 0"):
        _feedback(session=0)


@pytest.mark.parametrize(
    "name", ("seq", "tick", "host_session", "applied_seq", "late_commands", "crc_errors", "dropped_frames")
)
def test_feedback_u32_fields(name: str) -> None:
    assert getattr(_feedback(**{name: 0xFFFFFFFF}), name) == 0xFFFFFFFF
    for bad in (1 << 32, -1, False):
        with pytest.raises(p.ProtocolError, match=rf"^field: {name} must be an int in \[0, 2\*\*32\)"):
            _feedback(**{name: bad})


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"counts": (0,)}, r"counts must be a tuple of 2 ints, got \(0,\)"),
        ({"counts": [0, 0]}, r"counts must be a tuple of 2 ints"),
        ({"counts": (0, 1 << 32)}, r"counts must be an int in \[0, 2\*\*32\)"),
        ({"counts": (-1, 0)}, r"counts must be an int"),
        ({"adc": (0, 0, 0)}, r"adc must be a tuple of 4 ints, got \(0, 0, 0\)"),
        ({"adc": [0, 0, 0, 0]}, r"adc must be a tuple of 4 ints"),
        ({"adc": (0, 0, 0, 4096)}, r"adc must be an int in \[0, 2\*\*12\), got 4096"),
        ({"status": 1 << 16}, r"status must be an int in \[0, 2\*\*16\)"),
        ({"status": 0x20}, r"status has undefined bits set: 0x0020"),
        ({"faults": 1 << 16}, r"faults must be an int in \[0, 2\*\*16\)"),
        ({"applied_age": 1 << 16}, r"applied_age must be an int in \[0, 2\*\*16\)"),
        ({"output_codes": (0, 32768)}, r"output_codes must hold ints in \[-32767, 32767\]"),
        ({"output_codes": (0,)}, r"output_codes must be a tuple of 2 ints"),
    ],
)
def test_feedback_field_checks(fields: dict[str, object], message: str) -> None:
    with pytest.raises(p.ProtocolError, match=rf"^field: {message}") as caught:
        _feedback(**fields)
    assert caught.value.reason is p.Reason.FIELD


def test_feedback_ranges_accept_their_ends() -> None:
    frame = _feedback(
        counts=(0xFFFFFFFF, 0),
        adc=(4095, 0, 4095, 0),
        status=0x1F,
        faults=0xFFFF,
        output_codes=(-32767, 32767),
    )
    assert p.decode(p.encode(frame)) == frame


def test_typed_decoders_say_what_they_expected() -> None:
    with pytest.raises(p.ProtocolError, match=r"^type: expected a command frame, got a feedback frame$"):
        p.decode_command(_feedback_bytes())
    with pytest.raises(p.ProtocolError, match=r"^type: expected a feedback frame, got a command frame$"):
        p.decode_feedback(_command_bytes())
    assert p.decode_feedback(_feedback_bytes()) == FEEDBACK


def test_serial_number_arithmetic_at_the_half_range() -> None:
    # RFC 1982 with (int32_t)(a - b): 2**31 - 1 ahead is newer, 2**31 ahead reads as -2**31 (older)
    assert p.u32_diff(0x7FFFFFFF, 0) == 0x7FFFFFFF
    assert p.u32_diff(0x80000000, 0) == -0x80000000
    assert p.u32_diff(0, 0x80000000) == -0x80000000
    assert p.u32_diff(0, 1) == -1
    assert p.seq_newer(0x7FFFFFFF, 0)
    assert not p.seq_newer(0x80000000, 0)
    assert not p.seq_newer(5, 5)
    assert p.seq_newer(6, 5)


@pytest.mark.parametrize(
    ("offset", "fmt", "value", "text"),
    [
        (8, "<I", 0, "session must be != 0 (0 means no session)"),
        *(
            (32 + 2 * c, "<H", 4096 + c, f"adc must be an int in [0, 2**12), got {4096 + c}")
            for c in range(4)
        ),
        (40, "<H", 0x8000, "status has undefined bits set: 0x8000"),
        (50, "<h", -32768, "output_codes must hold ints in [-32767, 32767], got (-32768, -32767)"),
        (52, "<h", -32768, "output_codes must hold ints in [-32767, 32767], got (1200, -32768)"),
    ],
)
def test_every_feedback_field_the_wire_can_get_wrong_is_caught_by_the_decoder(
    offset: int, fmt: str, value: int, text: str
) -> None:
    good = _feedback_bytes()
    body = good[:offset] + struct.pack(fmt, value) + good[offset + struct.calcsize(fmt) : -4]
    assert _reason(body + struct.pack("<I", zlib.crc32(body))) == (p.Reason.FIELD, f"field: {text}")


def test_decoded_and_trusted_frames_behave_as_checked_ones() -> None:
    decoded = p.decode_feedback(_feedback_bytes())
    assert decoded == FEEDBACK and hash(decoded) == hash(FEEDBACK) and repr(decoded) == repr(FEEDBACK)
    command = p.decode_command(_command_bytes())
    trusted = p.CommandFrame.trusted(
        **{f.name: getattr(COMMAND, f.name) for f in dataclasses.fields(COMMAND)}
    )
    for frame in (command, trusted):
        assert frame == COMMAND and hash(frame) == hash(COMMAND) and frame.enabled
        assert p.encode(frame) == _command_bytes()
        with pytest.raises(dataclasses.FrozenInstanceError):
            frame.seq = 1  # type: ignore[misc]
    with pytest.raises(p.ProtocolError, match=r"^field: session must be != 0"):
        dataclasses.replace(trusted, session=0)  # an externally built frame is still checked
    feedback = p.FeedbackFrame.trusted(*(getattr(FEEDBACK, f.name) for f in dataclasses.fields(FEEDBACK)))
    assert feedback == FEEDBACK and hash(feedback) == hash(FEEDBACK)
    assert p.encode(feedback) == _feedback_bytes()
    with pytest.raises(p.ProtocolError, match=r"^field: session must be != 0"):
        dataclasses.replace(feedback, session=0)
