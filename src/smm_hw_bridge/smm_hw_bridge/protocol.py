"""Wire format of the host <-> I/O board link (docs/HW_PROTOCOL.md): frames, encoder, parser. No ROS.

Every frame is little-endian: a 16-byte header, a fixed payload per frame type, and a trailing CRC-32
(IEEE 802.3, ``zlib.crc32``) over everything before it. :func:`decode` raises nothing but
:class:`ProtocolError` (its ``reason`` says why), whatever bytes it is given.
"""

from __future__ import annotations

import enum
import struct
import zlib
from dataclasses import dataclass, fields
from typing import Any, Final, TypeVar

__all__ = [
    "ADC_CHANNELS",
    "ADC_MAX",
    "CODE_MAX",
    "COMMAND_SIZE",
    "FEEDBACK_SIZE",
    "HEADER_SIZE",
    "MAGIC",
    "NO_COMMAND_AGE",
    "N_JOINTS",
    "VERSION",
    "CommandFlag",
    "CommandFrame",
    "FaultBit",
    "FeedbackFrame",
    "FrameType",
    "ProtocolError",
    "Reason",
    "StatusBit",
    "decode",
    "decode_command",
    "decode_feedback",
    "encode",
    "seq_newer",
    "u32_diff",
]

MAGIC: Final[int] = 0x424D4D53
"""Bytes ``b"SMMB"`` read as a little-endian u32."""
VERSION: Final[int] = 1
N_JOINTS: Final[int] = 2
ADC_CHANNELS: Final[int] = 4
ADC_MAX: Final[int] = 4095
"""Largest 12-bit A/D code."""
CODE_MAX: Final[int] = 32767
"""Largest |D/A code|; -32768 is not a valid output (the range is symmetric about the null code 0)."""
NO_COMMAND_AGE: Final[int] = 0xFFFF
"""``applied_age`` when no command is applied (or its age does not fit in 16 bits)."""
U32: Final[int] = 1 << 32

_HEADER: Final[struct.Struct] = struct.Struct("<IBBHII")
_COMMAND_BODY: Final[struct.Struct] = struct.Struct("<IIIHHhh")
_FEEDBACK_BODY: Final[struct.Struct] = struct.Struct("<IIII4HHHIHhhHIII")
_CRC: Final[struct.Struct] = struct.Struct("<I")
_COMMAND_PACK: Final[struct.Struct] = struct.Struct(_HEADER.format + _COMMAND_BODY.format[1:])
_FEEDBACK_PACK: Final[struct.Struct] = struct.Struct(_HEADER.format + _FEEDBACK_BODY.format[1:])
_FEEDBACK_FRAME: Final[struct.Struct] = struct.Struct(_FEEDBACK_PACK.format + _CRC.format[1:])
_BODY: Final[int] = 6
"""Values of the header in an unpacked frame; the body's follow."""
_PAD: Final[int] = 14
"""Index of the reserved (pad) field in an unpacked feedback body."""
HEADER_SIZE: Final[int] = _HEADER.size
COMMAND_SIZE: Final[int] = HEADER_SIZE + _COMMAND_BODY.size + _CRC.size
FEEDBACK_SIZE: Final[int] = HEADER_SIZE + _FEEDBACK_BODY.size + _CRC.size


class FrameType(enum.IntEnum):
    """Header byte 5."""

    COMMAND = 1
    FEEDBACK = 2


class CommandFlag(enum.IntFlag):
    """Command ``flags`` bits; the other bits must be 0."""

    ENABLE = 0x0001
    ESTOP = 0x0002
    REARM = 0x0004


class StatusBit(enum.IntFlag):
    """Feedback ``status`` bits; the other bits are 0 in version 1."""

    ENABLED = 0x0001
    ESTOP_LATCHED = 0x0002
    HOLDING = 0x0004
    WATCHDOG = 0x0008
    HOST_LOCKED = 0x0010


class FaultBit(enum.IntFlag):
    """Feedback ``faults`` bits; any set bit means the board has put the valves at null by itself."""

    SUPPLY_LOW = 0x0001
    VALVE_DRIVER = 0x0002
    ENCODER = 0x0004
    DAC = 0x0008
    OVERTEMP = 0x0010
    INTERNAL = 0x8000


_COMMAND_FLAGS_MASK: Final[int] = int(CommandFlag.ENABLE | CommandFlag.ESTOP | CommandFlag.REARM)
_ENABLE: Final[int] = int(CommandFlag.ENABLE)
_STATUS_MASK: Final[int] = 0x001F
_COMMAND_TYPE: Final[int] = int(FrameType.COMMAND)
_FEEDBACK_TYPE: Final[int] = int(FrameType.FEEDBACK)
_CODE_MIN_WIRE: Final[int] = -CODE_MAX - 1
"""The one value of a signed 16-bit code field that is not a valid code."""


class Reason(enum.Enum):
    """Why a frame was rejected (each has its counter in the bridge's and the board's diagnostics)."""

    LENGTH = "length"
    MAGIC = "magic"
    CRC = "crc"
    VERSION = "version"
    TYPE = "type"
    FIELD = "field"
    FRAMING = "framing"
    SESSION = "session"
    SOURCE = "source"
    DUPLICATE = "duplicate"
    OUT_OF_ORDER = "out_of_order"
    STALE = "stale"


class ProtocolError(ValueError):
    """A frame that must not be used; ``reason`` says why.

    Args:
        reason: The rejection class.
        detail: Human-readable detail (values found and expected).
    """

    def __init__(self, reason: Reason, detail: str) -> None:
        super().__init__(f"{reason.value}: {detail}")
        self.reason = reason


def _check_u(name: str, value: int, bits: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < (1 << bits):
        raise ProtocolError(Reason.FIELD, f"{name} must be an int in [0, 2**{bits}), got {value!r}")


def _check_codes(name: str, codes: tuple[int, ...], limit: int) -> None:
    if not isinstance(codes, tuple) or len(codes) != N_JOINTS:
        raise ProtocolError(Reason.FIELD, f"{name} must be a tuple of {N_JOINTS} ints, got {codes!r}")
    for code in codes:
        if isinstance(code, bool) or not isinstance(code, int) or not -limit <= code <= limit:
            raise ProtocolError(Reason.FIELD, f"{name} must hold ints in [-{limit}, {limit}], got {codes!r}")


@dataclass(frozen=True)
class CommandFrame:
    """Host -> board (40 bytes).

    Attributes:
        session: Host session id (new at every bridge configure), u32, != 0.
        seq: Command sequence number, u32 (wraps).
        board_session: Board session this command is for; the board drops any other, u32.
        answers_seq: Sequence of the feedback frame this command answers, u32.
        answers_tick: Board tick of that feedback frame, u32.
        flags: :class:`CommandFlag` bits.
        validity: Ticks after ``answers_tick`` during which the board may apply this command, u16.
        codes: D/A code per joint (alpha, beta), in [-32767, 32767]; 0 = valve null.
    """

    session: int
    seq: int
    board_session: int
    answers_seq: int
    answers_tick: int
    flags: int
    validity: int
    codes: tuple[int, int]

    def __post_init__(self) -> None:
        for name in ("session", "seq", "board_session", "answers_seq", "answers_tick"):
            _check_u(name, getattr(self, name), 32)
        if self.session == 0:
            raise ProtocolError(Reason.FIELD, "session must be != 0 (0 means no session)")
        _check_u("flags", self.flags, 16)
        if self.flags & ~_COMMAND_FLAGS_MASK:
            raise ProtocolError(Reason.FIELD, f"flags has undefined bits set: {self.flags:#06x}")
        _check_u("validity", self.validity, 16)
        _check_codes("codes", self.codes, CODE_MAX)

    @classmethod
    def trusted(
        cls,
        *,
        session: int,
        seq: int,
        board_session: int,
        answers_seq: int,
        answers_tick: int,
        flags: int,
        validity: int,
        codes: tuple[int, int],
    ) -> CommandFrame:
        """A frame whose fields the caller has already checked (its own validated state), built unchecked."""
        return _unchecked(
            cls,
            _COMMAND_FIELDS,
            (session, seq, board_session, answers_seq, answers_tick, flags, validity, codes),
        )

    @property
    def enabled(self) -> bool:
        """ENABLE flag set."""
        return bool(self.flags & _ENABLE)


@dataclass(frozen=True)
class FeedbackFrame:
    """Board -> host (72 bytes).

    Attributes:
        session: Board session id (new at every board boot), u32, != 0.
        seq: Feedback sequence number, u32 (wraps).
        tick: Board tick (1 kHz clock since boot) at which the encoders were sampled, u32 (wraps).
        host_session: Host session the board is locked to (0 = none yet), u32.
        counts: Raw encoder counter per joint, u32 (the counter wraps modulo ``2**counter_bits``).
        adc: 12-bit A/D channels: 0 = supply pressure, 1-3 spare, each in [0, 4095].
        status: :class:`StatusBit` bits.
        faults: :class:`FaultBit` bits.
        applied_seq: Sequence of the command being applied (0 with ``applied_age`` = 0xFFFF: none).
        applied_age: ``tick`` minus that command's ``answers_tick`` (ticks), 0xFFFF = none / too old.
        output_codes: D/A codes on the valves now (after hold, ramp, e-stop), in [-32767, 32767].
        late_commands: Ticks at which the answer to the previous feedback had not arrived (held), u32.
        crc_errors: Received frames with a bad CRC, u32.
        dropped_frames: Other received frames not applied (length, magic, version, type, field, session,
            expired validity), u32.
    """

    session: int
    seq: int
    tick: int
    host_session: int
    counts: tuple[int, int]
    adc: tuple[int, int, int, int]
    status: int
    faults: int
    applied_seq: int
    applied_age: int
    output_codes: tuple[int, int]
    late_commands: int
    crc_errors: int
    dropped_frames: int

    def __post_init__(self) -> None:
        for name in ("session", "seq", "tick", "host_session", "applied_seq"):
            _check_u(name, getattr(self, name), 32)
        if self.session == 0:
            raise ProtocolError(Reason.FIELD, "session must be != 0 (0 means no session)")
        for name in ("late_commands", "crc_errors", "dropped_frames"):
            _check_u(name, getattr(self, name), 32)
        if not isinstance(self.counts, tuple) or len(self.counts) != N_JOINTS:
            raise ProtocolError(
                Reason.FIELD, f"counts must be a tuple of {N_JOINTS} ints, got {self.counts!r}"
            )
        for count in self.counts:
            _check_u("counts", count, 32)
        if not isinstance(self.adc, tuple) or len(self.adc) != ADC_CHANNELS:
            raise ProtocolError(Reason.FIELD, f"adc must be a tuple of {ADC_CHANNELS} ints, got {self.adc!r}")
        for value in self.adc:
            _check_u("adc", value, 12)
        _check_u("status", self.status, 16)
        if self.status & ~_STATUS_MASK:
            raise ProtocolError(Reason.FIELD, f"status has undefined bits set: {self.status:#06x}")
        _check_u("faults", self.faults, 16)
        _check_u("applied_age", self.applied_age, 16)
        _check_codes("output_codes", self.output_codes, CODE_MAX)

    @classmethod
    def trusted(cls, *values: Any) -> FeedbackFrame:
        """A frame of the fields in their order, which the caller keeps in range (the board's own state)."""
        return _unchecked(cls, _FEEDBACK_FIELDS, values)


_Frame = TypeVar("_Frame", CommandFrame, FeedbackFrame)
_COMMAND_FIELDS: Final[tuple[str, ...]] = tuple(item.name for item in fields(CommandFrame))
_FEEDBACK_FIELDS: Final[tuple[str, ...]] = tuple(item.name for item in fields(FeedbackFrame))


def _unchecked(cls: type[_Frame], names: tuple[str, ...], values: tuple[Any, ...]) -> _Frame:
    """A frame of ``cls`` without ``__post_init__``: for values its checks are known to pass."""
    frame = object.__new__(cls)
    frame.__dict__.update(zip(names, values, strict=False))  # both from the field list: equal lengths
    return frame


def u32_diff(a: int, b: int) -> int:
    """``a - b`` of two wrapping u32 counters, as a signed int in [-2**31, 2**31)."""
    return ((a - b + (1 << 31)) % U32) - (1 << 31)


def seq_newer(a: int, b: int) -> bool:
    """True if u32 sequence ``a`` is after ``b`` (serial-number arithmetic, RFC 1982)."""
    return u32_diff(a, b) > 0


def encode(frame: CommandFrame | FeedbackFrame) -> bytes:
    """The frame's bytes, CRC included."""
    if isinstance(frame, CommandFrame):
        data = _COMMAND_PACK.pack(
            MAGIC,
            VERSION,
            _COMMAND_TYPE,
            COMMAND_SIZE,
            frame.session,
            frame.seq,
            frame.board_session,
            frame.answers_seq,
            frame.answers_tick,
            frame.flags,
            frame.validity,
            *frame.codes,
        )
    else:
        data = _FEEDBACK_PACK.pack(
            MAGIC,
            VERSION,
            _FEEDBACK_TYPE,
            FEEDBACK_SIZE,
            frame.session,
            frame.seq,
            frame.tick,
            frame.host_session,
            *frame.counts,
            *frame.adc,
            frame.status,
            frame.faults,
            frame.applied_seq,
            frame.applied_age,
            *frame.output_codes,
            0,
            frame.late_commands,
            frame.crc_errors,
            frame.dropped_frames,
        )
    return data + _CRC.pack(zlib.crc32(data))


def decode(data: bytes | bytearray | memoryview) -> CommandFrame | FeedbackFrame:
    """Parses one frame, checking in the order of docs/HW_PROTOCOL.md.

    Raises:
        ProtocolError: The only exception; ``reason`` is LENGTH, MAGIC, CRC, VERSION, TYPE or FIELD.
    """
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise ProtocolError(Reason.FIELD, f"not a byte buffer: {type(data).__name__}")
    raw = bytes(data)
    if len(raw) < HEADER_SIZE + _CRC.size:
        raise ProtocolError(Reason.LENGTH, f"{len(raw)} bytes is shorter than header + CRC")
    magic, version, frame_type, length, session, seq = _HEADER.unpack_from(raw)
    if magic != MAGIC:
        raise ProtocolError(Reason.MAGIC, f"magic {magic:#010x}, expected {MAGIC:#010x}")
    if length != len(raw):
        raise ProtocolError(Reason.LENGTH, f"length field {length}, datagram {len(raw)} bytes")
    (crc,) = _CRC.unpack_from(raw, len(raw) - _CRC.size)
    computed = zlib.crc32(raw[: -_CRC.size])
    if crc != computed:
        raise ProtocolError(Reason.CRC, f"CRC {crc:#010x}, computed {computed:#010x}")
    if version != VERSION:
        raise ProtocolError(Reason.VERSION, f"protocol version {version}, this side speaks {VERSION}")
    if frame_type == _COMMAND_TYPE:
        expected = COMMAND_SIZE
    elif frame_type == _FEEDBACK_TYPE:
        expected = FEEDBACK_SIZE
    else:
        raise ProtocolError(Reason.TYPE, f"frame type {frame_type}")
    if length != expected:
        raise ProtocolError(
            Reason.LENGTH, f"{FrameType(frame_type).name} frame of {length} bytes, expected {expected}"
        )
    if frame_type == _COMMAND_TYPE:
        board_session, answers_seq, answers_tick, flags, validity, code_a, code_b = _COMMAND_BODY.unpack_from(
            raw, HEADER_SIZE
        )
        command = (session, seq, board_session, answers_seq, answers_tick, flags, validity, (code_a, code_b))
        # struct's unsigned fields are in range: only what a wire frame can get wrong is checked here; a
        # frame that fails goes through the checking constructor, which names the field
        if session and not flags & ~_COMMAND_FLAGS_MASK and _CODE_MIN_WIRE not in (code_a, code_b):
            return _unchecked(CommandFrame, _COMMAND_FIELDS, command)
        return CommandFrame(*command)
    body = _FEEDBACK_BODY.unpack_from(raw, HEADER_SIZE)
    if body[_PAD] != 0:
        raise ProtocolError(Reason.FIELD, f"reserved field is {body[_PAD]}, must be 0")
    feedback, plain = _feedback_fields(session, seq, body)
    if plain:
        return _unchecked(FeedbackFrame, _FEEDBACK_FIELDS, feedback)
    return FeedbackFrame(*feedback)


def _feedback_fields(session: int, seq: int, body: tuple[Any, ...]) -> tuple[tuple[Any, ...], bool]:
    """A feedback frame's fields from the header's session and seq and the unpacked body, and whether plain.

    Plain: no field needs the checking constructor (struct's unsigned fields are in range; what a wire
    frame can still get wrong is the session, status bits, A/D range and the code -32768).
    """
    (
        tick,
        host_session,
        count_a,
        count_b,
        adc0,
        adc1,
        adc2,
        adc3,
        status,
        faults,
        applied_seq,
        applied_age,
        out_a,
        out_b,
        _,
        late,
        crc_errors,
        dropped,
    ) = body
    feedback = (
        session,
        seq,
        tick,
        host_session,
        (count_a, count_b),
        (adc0, adc1, adc2, adc3),
        status,
        faults,
        applied_seq,
        applied_age,
        (out_a, out_b),
        late,
        crc_errors,
        dropped,
    )
    plain = (
        session != 0
        and not status & ~_STATUS_MASK
        and max(adc0, adc1, adc2, adc3) <= ADC_MAX
        and _CODE_MIN_WIRE not in (out_a, out_b)
    )
    return feedback, plain


def decode_command(data: bytes | bytearray | memoryview) -> CommandFrame:
    """:func:`decode`, and a TYPE error unless it is a command frame."""
    frame = decode(data)
    if not isinstance(frame, CommandFrame):
        raise ProtocolError(Reason.TYPE, "expected a command frame, got a feedback frame")
    return frame


def decode_feedback(data: bytes | bytearray | memoryview) -> FeedbackFrame:
    """:func:`decode`, and a TYPE error unless it is a feedback frame."""
    if type(data) is bytes and len(data) == FEEDBACK_SIZE:
        plain = _plain_feedback(data)
        if plain is not None:
            return plain
    frame = decode(data)
    if not isinstance(frame, FeedbackFrame):
        raise ProtocolError(Reason.TYPE, "expected a feedback frame, got a command frame")
    return frame


def _plain_feedback(raw: bytes) -> FeedbackFrame | None:
    """:func:`decode`'s frame for ``raw`` (FEEDBACK_SIZE bytes) in one unpack; None unless it is a plain one.

    Plain: a valid feedback frame whose fields need no check (the receiving thread's case); any other is
    left to :func:`decode`, which names what is wrong.
    """
    values = _FEEDBACK_FRAME.unpack(raw)
    magic, version, frame_type, length, session, seq = values[:_BODY]
    body = values[_BODY:-1]
    if (
        magic != MAGIC
        or length != FEEDBACK_SIZE
        or version != VERSION
        or frame_type != _FEEDBACK_TYPE
        or body[_PAD] != 0
        or values[-1] != zlib.crc32(raw[: -_CRC.size])
    ):
        return None
    feedback, plain = _feedback_fields(session, seq, body)
    return _unchecked(FeedbackFrame, _FEEDBACK_FIELDS, feedback) if plain else None
