"""Decoding many messages of one topic at once: a byte template per message length, numpy for the rest.

Messages of one topic and length almost always differ only in their stamp and their float values. For each
such group the first message is decoded the slow way (:mod:`smm_bag.cdr`), which gives the byte ranges of
the stamp and of the doubles; the group is accepted only if every other byte equals the first message's,
and the values are then read as numpy views. Any group that does not fit (other names, layouts, big-endian
data) is decoded message by message, so the result never depends on the shortcut.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from smm_bag.cdr import decode_float64_multi_array, decode_joint_state
from smm_bag.errors import CorruptBagError

__all__ = ["ArrayColumns", "JointColumns", "decode_arrays", "decode_joint_states"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
_NS = 1_000_000_000


@dataclass(frozen=True)
class JointColumns:
    """JointState messages of one group: stamps (n,), names, and (n, len(names)) arrays (None if empty)."""

    stamps: IntArray
    names: tuple[str, ...]
    position: FloatArray
    velocity: FloatArray | None
    effort: FloatArray | None


@dataclass(frozen=True)
class ArrayColumns:
    """Float64MultiArray messages of one group: stamps (n,), the dimension labels, data (n, k)."""

    stamps: IntArray
    labels: tuple[str, ...]
    data: FloatArray


def _groups(buffers: Sequence[bytes]) -> dict[int, list[int]]:
    groups: dict[int, list[int]] = {}
    for index, buffer in enumerate(buffers):
        groups.setdefault(len(buffer), []).append(index)
    return groups


def _matrix(buffers: Sequence[bytes], indices: list[int], length: int) -> NDArray[np.uint8]:
    joined = b"".join(buffers[i] for i in indices)
    return np.frombuffer(joined, dtype=np.uint8).reshape(len(indices), length)


def _constant_elsewhere(matrix: NDArray[np.uint8], variable: NDArray[np.bool_]) -> bool:
    constant = ~variable
    return bool(np.all(matrix[:, constant] == matrix[0, constant]))


def _doubles(matrix: NDArray[np.uint8], start: int, count: int) -> FloatArray:
    values: FloatArray = np.ascontiguousarray(matrix[:, start : start + 8 * count]).view("<f8")
    return values.reshape(matrix.shape[0], count)


def _joint_layout(buffer: bytes) -> tuple[tuple[str, ...], list[tuple[int, int]]] | None:
    """Names and (offset, count) of position, velocity, effort in a little-endian JointState."""
    if len(buffer) < 4 or buffer[1] != 1:
        return None
    decoded = decode_joint_state(buffer)
    # Re-walk the layout to find where each double sequence starts.
    position = 4 + 8  # stamp
    position = _skip_string(buffer, position)  # frame_id
    position = _align(position, 4)
    count = int.from_bytes(buffer[position : position + 4], "little")
    position += 4
    if count != len(decoded.name):
        return None
    for _ in range(count):
        position = _skip_string(buffer, position)
    ranges = []
    for values in (decoded.position, decoded.velocity, decoded.effort):
        position = _align(position, 4) + 4
        if values:
            position = _align(position, 8)
        ranges.append((position, len(values)))
        position += 8 * len(values)
    return decoded.name, ranges


def _align(position: int, size: int) -> int:
    offset = (position - 4) % size
    return position + (size - offset if offset else 0)


def _skip_string(buffer: bytes, position: int) -> int:
    position = _align(position, 4)
    length = int.from_bytes(buffer[position : position + 4], "little")
    return position + 4 + length


def decode_joint_states(buffers: Sequence[bytes]) -> list[tuple[list[int], JointColumns]]:
    """Decodes JointState messages; returns per group the message indices and their columns.

    Raises:
        CorruptBagError: A message is not a JointState in CDR.
    """
    result = []
    for length, indices in _groups(buffers).items():
        layout = _joint_layout(buffers[indices[0]])
        if layout is not None and length >= 12:
            names, ranges = layout
            matrix = _matrix(buffers, indices, length)
            variable = np.zeros(length, dtype=bool)
            variable[4:12] = True
            for start, count in ranges:
                variable[start : start + 8 * count] = True
            if _constant_elsewhere(matrix, variable):
                sec = np.ascontiguousarray(matrix[:, 4:8]).view("<i4").astype(np.int64).ravel()
                nanosec = np.ascontiguousarray(matrix[:, 8:12]).view("<u4").astype(np.int64).ravel()
                columns = [_doubles(matrix, start, count) if count else None for start, count in ranges]
                position = columns[0] if columns[0] is not None else np.zeros((len(indices), 0))
                result.append(
                    (indices, JointColumns(sec * _NS + nanosec, names, position, columns[1], columns[2]))
                )
                continue
        result.extend(_slow_joint_states(buffers, indices))
    return result


def _slow_joint_states(buffers: Sequence[bytes], indices: list[int]) -> list[tuple[list[int], JointColumns]]:
    out = []
    for index in indices:
        state = decode_joint_state(buffers[index])
        width = len(state.name)

        def row(values: tuple[float, ...], width: int = width) -> FloatArray | None:
            if not values:
                return None
            if len(values) != width:
                raise CorruptBagError(f"JointState with {width} names has {len(values)} values")
            return np.array([values])

        position = row(state.position)
        out.append(
            (
                [index],
                JointColumns(
                    np.array([state.stamp_ns], dtype=np.int64),
                    state.name,
                    position if position is not None else np.zeros((1, 0)),
                    row(state.velocity),
                    row(state.effort),
                ),
            )
        )
    return out


def _array_layout(buffer: bytes) -> tuple[tuple[str, ...], tuple[int, int], tuple[int, int]] | None:
    """Labels, (start, end) of the stamp digits, (offset, count) of the data in a little-endian array."""
    if len(buffer) < 4 or buffer[1] != 1:
        return None
    decoded = decode_float64_multi_array(buffer)
    position = 4 + 4  # dims count
    digits = None
    for label, _, _ in decoded.dims:
        position = _align(position, 4)
        start = position + 4
        position = start + len(label.encode("utf-8")) + 1
        if label.startswith("stamp_ns:"):
            digits = (start + len("stamp_ns:"), start + len(label))
        position = _align(position, 4) + 8  # size, stride
    position = _align(position, 4) + 4  # data_offset
    position = _align(position, 4) + 4  # data count
    count = len(decoded.data)
    if count:
        position = _align(position, 8)
    if digits is None or digits[1] <= digits[0] or position + 8 * count != len(buffer):
        return None
    return tuple(label for label, _, _ in decoded.dims), digits, (position, count)


def decode_arrays(buffers: Sequence[bytes]) -> list[tuple[list[int], ArrayColumns]]:
    """Decodes stamped Float64MultiArray messages; returns per group the message indices and columns.

    Raises:
        CorruptBagError: A message is not a Float64MultiArray in CDR or has no ``stamp_ns`` dimension.
    """
    result = []
    for length, indices in _groups(buffers).items():
        layout = _array_layout(buffers[indices[0]])
        if layout is None:
            result.extend(_slow_arrays(buffers, indices))
            continue
        # Stamps of different digit counts can pad to the same length: split on the stamp label's length.
        length_field = layout[1][0] - len("stamp_ns:") - 4
        matrix = _matrix(buffers, indices, length)
        label_lengths = np.ascontiguousarray(matrix[:, length_field : length_field + 4]).view("<u4").ravel()
        for value in np.unique(label_lengths):
            chosen = [indices[k] for k in np.nonzero(label_lengths == value)[0]]
            result.extend(_array_group(buffers, chosen, length))
    return result


def _array_group(
    buffers: Sequence[bytes], indices: list[int], length: int
) -> list[tuple[list[int], ArrayColumns]]:
    layout = _array_layout(buffers[indices[0]])
    if layout is None:
        return _slow_arrays(buffers, indices)
    labels, (first, last), (start, count) = layout
    matrix = _matrix(buffers, indices, length)
    variable = np.zeros(length, dtype=bool)
    variable[first:last] = True
    variable[start : start + 8 * count] = True
    digits = matrix[:, first:last].astype(np.int64) - 48
    if not (_constant_elsewhere(matrix, variable) and np.all((digits >= 0) & (digits <= 9))):
        return _slow_arrays(buffers, indices)
    weights = 10 ** np.arange(last - first - 1, -1, -1, dtype=np.int64)
    stamps: IntArray = digits @ weights
    clean = (*labels[:-1], "stamp_ns:")
    return [(indices, ArrayColumns(stamps, clean, _doubles(matrix, start, count)))]


def _slow_arrays(buffers: Sequence[bytes], indices: list[int]) -> list[tuple[list[int], ArrayColumns]]:
    result = []
    for index in indices:
        decoded = decode_float64_multi_array(buffers[index])
        stamp = decoded.stamp_ns
        if stamp is None:
            raise CorruptBagError("Float64MultiArray without a stamp_ns dimension")
        labels = tuple(label for label, _, _ in decoded.dims)
        clean = (*labels[:-1], "stamp_ns:")
        result.append(
            ([index], ArrayColumns(np.array([stamp], dtype=np.int64), clean, np.array([decoded.data])))
        )
    return result
