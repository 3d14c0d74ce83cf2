"""Fast CDR decoding of the two message types the analysis reads, and of the stamps loss accounting needs.

Only ``sensor_msgs/JointState`` and ``std_msgs/Float64MultiArray`` (XCDR1 plain CDR, either byte order,
alignment relative to the payload after the 4-byte encapsulation header). A generic decoder (mcap-ros2) is
10-20 times slower; tests check these against rclpy's own serialisation.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from smm_bag.errors import CorruptBagError

__all__ = [
    "DecodedArray",
    "DecodedJointState",
    "decode_float64_multi_array",
    "decode_joint_state",
    "encode_float64_multi_array",
    "encode_joint_state",
    "stamp_of",
]

_ORDER = {0: ">", 1: "<"}
_NS = 1_000_000_000
_STAMP_PREFIX = "stamp_ns:"


@dataclass(frozen=True)
class DecodedJointState:
    """``sensor_msgs/JointState``: stamp (ns), names and the three float arrays (tuples, possibly empty)."""

    stamp_ns: int
    name: tuple[str, ...]
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    effort: tuple[float, ...]


@dataclass(frozen=True)
class DecodedArray:
    """``std_msgs/Float64MultiArray``: dimension (label, size, stride) triples, data offset and data."""

    dims: tuple[tuple[str, int, int], ...]
    data_offset: int
    data: tuple[float, ...]

    @property
    def stamp_ns(self) -> int | None:
        """The stamp of the stamp rule (last dimension ``stamp_ns:<int>``), or None."""
        if not self.dims:
            return None
        label = self.dims[-1][0]
        if not label.startswith(_STAMP_PREFIX):
            return None
        digits = label[len(_STAMP_PREFIX) :]
        return int(digits) if digits.isdigit() else None

    def items(self, dimension: str) -> tuple[str, ...] | None:
        """Item names of the dimension labelled ``<dimension>:a,b,...``, or None."""
        prefix = dimension + ":"
        for label, _, _ in self.dims:
            if label.startswith(prefix):
                return tuple(label[len(prefix) :].split(","))
        return None


class _Cursor:
    __slots__ = ("buffer", "order", "position")

    def __init__(self, buffer: bytes) -> None:
        if len(buffer) < 4:
            raise CorruptBagError(f"CDR message of {len(buffer)} bytes has no encapsulation header")
        order = _ORDER.get(buffer[1])
        if buffer[0] != 0 or order is None:
            raise CorruptBagError(f"unsupported CDR encapsulation {buffer[:2].hex()}")
        self.buffer = buffer
        self.order = order
        self.position = 4

    def align(self, size: int) -> None:
        offset = (self.position - 4) % size
        if offset:
            self.position += size - offset

    def uint32(self) -> int:
        self.align(4)
        (value,) = struct.unpack_from(self.order + "I", self.buffer, self.position)
        self.position += 4
        return int(value)

    def int32(self) -> int:
        self.align(4)
        (value,) = struct.unpack_from(self.order + "i", self.buffer, self.position)
        self.position += 4
        return int(value)

    def string(self) -> str:
        length = self.uint32()
        end = self.position + length
        if length == 0 or end > len(self.buffer) or self.buffer[end - 1] != 0:
            raise CorruptBagError("CDR string without terminator or past the end of the message")
        text = self.buffer[self.position : end - 1].decode("utf-8")
        self.position = end
        return text

    def doubles(self) -> tuple[float, ...]:
        count = self.uint32()
        if count == 0:
            return ()
        self.align(8)
        values = struct.unpack_from(f"{self.order}{count}d", self.buffer, self.position)
        self.position += 8 * count
        return tuple(values)


def decode_joint_state(buffer: bytes) -> DecodedJointState:
    """Decodes a serialized ``sensor_msgs/JointState``.

    Raises:
        CorruptBagError: The bytes are not a JointState in CDR.
    """
    try:
        cursor = _Cursor(buffer)
        sec = cursor.int32()
        nanosec = cursor.uint32()
        cursor.string()  # frame_id
        names = tuple(cursor.string() for _ in range(cursor.uint32()))
        position = cursor.doubles()
        velocity = cursor.doubles()
        effort = cursor.doubles()
    except (struct.error, UnicodeDecodeError, MemoryError) as error:
        raise CorruptBagError(f"malformed JointState CDR: {error}") from None
    return DecodedJointState(sec * _NS + nanosec, names, position, velocity, effort)


def decode_float64_multi_array(buffer: bytes) -> DecodedArray:
    """Decodes a serialized ``std_msgs/Float64MultiArray``.

    Raises:
        CorruptBagError: The bytes are not a Float64MultiArray in CDR.
    """
    try:
        cursor = _Cursor(buffer)
        dims = []
        for _ in range(cursor.uint32()):
            label = cursor.string()
            size = cursor.uint32()
            stride = cursor.uint32()
            dims.append((label, size, stride))
        data_offset = cursor.uint32()
        data = cursor.doubles()
    except (struct.error, UnicodeDecodeError, MemoryError) as error:
        raise CorruptBagError(f"malformed Float64MultiArray CDR: {error}") from None
    return DecodedArray(tuple(dims), data_offset, data)


def stamp_of(type_name: str, buffer: bytes) -> int | None:
    """The stamp (ns) of a JointState header, a stamped Float64MultiArray or a Clock; None for other types."""
    if type_name in ("sensor_msgs/msg/JointState", "rosgraph_msgs/msg/Clock"):
        if len(buffer) < 12:
            return None
        order = _ORDER.get(buffer[1], "<")
        sec, nanosec = struct.unpack_from(order + "iI", buffer, 4)
        return int(sec) * _NS + int(nanosec)
    if type_name == "std_msgs/msg/Float64MultiArray":
        try:
            return decode_float64_multi_array(buffer).stamp_ns
        except CorruptBagError:
            return None
    return None


class _Builder:
    __slots__ = ("parts", "size")

    def __init__(self) -> None:
        self.parts: list[bytes] = [b"\x00\x01\x00\x00"]
        self.size = 0  # payload bytes so far (alignment is relative to the payload)

    def _pad(self, alignment: int) -> None:
        offset = self.size % alignment
        if offset:
            self.parts.append(b"\x00" * (alignment - offset))
            self.size += alignment - offset

    def uint32(self, value: int) -> None:
        self._pad(4)
        self.parts.append(struct.pack("<I", value))
        self.size += 4

    def int32(self, value: int) -> None:
        self._pad(4)
        self.parts.append(struct.pack("<i", value))
        self.size += 4

    def string(self, text: str) -> None:
        encoded = text.encode("utf-8") + b"\x00"
        self.uint32(len(encoded))
        self.parts.append(encoded)
        self.size += len(encoded)

    def doubles(self, values: tuple[float, ...] | list[float]) -> None:
        self.uint32(len(values))
        if values:
            self._pad(8)
            self.parts.append(struct.pack(f"<{len(values)}d", *values))
            self.size += 8 * len(values)

    def bytes(self) -> bytes:
        return b"".join(self.parts)


def encode_joint_state(
    stamp_ns: int,
    name: tuple[str, ...] | list[str],
    position: tuple[float, ...] | list[float],
    velocity: tuple[float, ...] | list[float] = (),
    effort: tuple[float, ...] | list[float] = (),
    *,
    frame_id: str = "",
) -> bytes:
    """Serializes a ``sensor_msgs/JointState`` in little-endian CDR, as it travels on the wire."""
    builder = _Builder()
    builder.int32(stamp_ns // _NS)
    builder.uint32(stamp_ns % _NS)
    builder.string(frame_id)
    builder.uint32(len(name))
    for item in name:
        builder.string(item)
    builder.doubles(list(position))
    builder.doubles(list(velocity))
    builder.doubles(list(effort))
    return builder.bytes()


def encode_float64_multi_array(
    dims: tuple[tuple[str, int, int], ...] | list[tuple[str, int, int]],
    data: tuple[float, ...] | list[float],
    data_offset: int = 0,
) -> bytes:
    """Serializes a ``std_msgs/Float64MultiArray`` in little-endian CDR, as it travels on the wire."""
    builder = _Builder()
    builder.uint32(len(dims))
    for label, size, stride in dims:
        builder.string(label)
        builder.uint32(size)
        builder.uint32(stride)
    builder.uint32(data_offset)
    builder.doubles(list(data))
    return builder.bytes()
