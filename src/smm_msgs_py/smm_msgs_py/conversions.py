"""Message <-> numpy conversions of the SMM interface, validating both ways.

Stamp rule (see ``docs/INTERFACES.md``): ``Float64MultiArray`` has no header, so every one we publish ends
with a size-1 dimension labelled ``stamp_ns:<int>``: the integer nanoseconds since the epoch of the
``header.stamp`` of the measurement it answers (simulation time in lockstep). The other dimensions are
labelled ``<dimname>:<comma-separated item names>`` with ROS strides (``dim[i].stride`` = product of the
sizes of ``dim[i:]``) and ``data_offset == 0``, so the product of the sizes equals ``len(data)`` and generic
consumers see a plain 2-vector or (n, 2) array.

Converting to a message validates (shape, NaN/Inf, stamp) so that no bad value is ever published; converting
from a message validates everything and raises an :class:`~smm_msgs_py.errors.InterfaceError` subclass.

Speed: these run several times per 1 kHz step, so labels of fixed layouts are precomputed, free labels are
parsed once and cached, no regular expression is used, and arrays travel as ``array.array('d')`` buffers
(the type rclpy stores sequences of doubles in), never as Python lists of floats.
"""

from __future__ import annotations

import array
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Final, NamedTuple

import numpy as np
import numpy.typing as npt
from builtin_interfaces.msg import Time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from smm_msgs_py.errors import ArrayLengthError, JointNameError, LayoutError, NonFiniteError, StampError
from smm_msgs_py.joints import JOINT_NAMES, NUM_JOINTS
from smm_msgs_py.layouts import (
    DIM_SEPARATOR,
    ITEM_SEPARATOR,
    JOINT_DIM,
    ORDER_DIM,
    QUANTITY_DIM,
    REFERENCE_ROWS,
    STAMP_DIM,
)

FloatArray = npt.NDArray[np.float64]

NANOSECONDS_PER_SECOND: Final[int] = 1_000_000_000
MAX_STAMP_NS: Final[int] = (2**31 - 1) * NANOSECONDS_PER_SECOND + NANOSECONDS_PER_SECOND - 1
"""Largest stamp a ``builtin_interfaces/Time`` can hold (int32 sec, nanosec < 1e9), in ns (about 2.1e18)."""

TORQUE_SHAPE: Final[tuple[int]] = (NUM_JOINTS,)
REFERENCE_SHAPE: Final[tuple[int, int]] = (len(REFERENCE_ROWS), NUM_JOINTS)

_STAMP_PREFIX: Final[str] = STAMP_DIM + DIM_SEPARATOR
_JOINT_NAME_LIST: Final[list[str]] = list(JOINT_NAMES)
_FORBIDDEN_IN_ITEM: Final[frozenset[str]] = frozenset((DIM_SEPARATOR, ITEM_SEPARATOR))


class _Axis(NamedTuple):
    """One data dimension of a layout: its name and, when fixed, its items and full label."""

    name: str
    items: tuple[str, ...] | None = None  # None: the parser accepts any valid item names
    label: str | None = None


# ---------------------------------------------------------------------------------------------- stamps


def _checked_stamp_ns(stamp_ns: object) -> int:
    """Return ``stamp_ns`` as an int in [0, MAX_STAMP_NS], or raise StampError."""
    if type(stamp_ns) is not int:
        # bool is an int subclass but never a stamp; numpy integers are accepted.
        if isinstance(stamp_ns, bool) or not isinstance(stamp_ns, (int, np.integer)):
            raise StampError(f"stamp_ns must be an integer number of ns, got {stamp_ns!r}")
        stamp_ns = int(stamp_ns)
    if not 0 <= stamp_ns <= MAX_STAMP_NS:
        raise StampError(f"stamp_ns={stamp_ns} outside [0, {MAX_STAMP_NS}] (builtin_interfaces/Time range)")
    return stamp_ns


def stamp_to_ns(stamp: Time) -> int:
    """Convert a ``builtin_interfaces/Time`` to integer nanoseconds since the epoch.

    Args:
        stamp: Time with ``sec >= 0`` and ``0 <= nanosec < 1e9``.

    Returns:
        ``sec * 10**9 + nanosec`` (ns), exact.

    Raises:
        StampError: negative time or a non-normalised ``nanosec``.
    """
    sec: int = stamp.sec
    nanosec: int = stamp.nanosec
    if sec < 0:
        raise StampError(f"negative stamp: sec={sec}")
    if nanosec >= NANOSECONDS_PER_SECOND:
        raise StampError(f"nanosec={nanosec} is not below 1e9 (stamp not normalised)")
    return sec * NANOSECONDS_PER_SECOND + nanosec


def ns_to_stamp(stamp_ns: int) -> Time:
    """Convert integer nanoseconds since the epoch to a ``builtin_interfaces/Time``.

    Args:
        stamp_ns: Stamp in ns, in [0, :data:`MAX_STAMP_NS`].

    Returns:
        The normalised Time (``0 <= nanosec < 1e9``).

    Raises:
        StampError: negative, not an integer, or beyond the int32 ``sec`` range.
    """
    sec, nanosec = divmod(_checked_stamp_ns(stamp_ns), NANOSECONDS_PER_SECOND)
    return Time(sec=sec, nanosec=nanosec)


def clock_msg(stamp_ns: int) -> Clock:
    """Build the ``rosgraph_msgs/Clock`` the simulator publishes on ``/clock``.

    Args:
        stamp_ns: Simulation time in ns.

    Returns:
        The Clock message.

    Raises:
        StampError: invalid stamp (see :func:`ns_to_stamp`).
    """
    return Clock(clock=ns_to_stamp(stamp_ns))


# ----------------------------------------------------------------------------------- validated arrays


def _frozen_copy(values: npt.ArrayLike, field: str) -> FloatArray:
    """Return a read-only float64 copy of ``values``; raise NonFiniteError on NaN/Inf."""
    try:
        copied = np.array(values, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ArrayLengthError(f"{field}: not a rectangular array of numbers ({error})") from error
    # math.isfinite over a list is ~8x faster than np.isfinite(...).all() for the few values we carry.
    if not all(map(math.isfinite, copied.ravel().tolist())):
        bad = np.argwhere(~np.isfinite(copied)).tolist()
        raise NonFiniteError(f"{field}: non-finite value(s) {copied[~np.isfinite(copied)]} at index {bad}")
    copied.flags.writeable = False
    return copied


def _require_shape(values: FloatArray, shape: tuple[int, ...], field: str) -> None:
    if values.shape != shape:
        raise ArrayLengthError(f"{field}: expected shape {shape}, got {values.shape}")


@dataclass(frozen=True, eq=False)
class JointSample:
    """One joint-state sample in the stack's joint order (alpha, beta).

    Arrays are validated (shape (2,), finite) and stored as read-only float64 copies. ``eq=False`` because
    element-wise numpy comparison has no single truth value; compare fields with ``numpy.testing``.

    Attributes:
        stamp_ns: Sample time (ns since epoch; simulation time in lockstep).
        position: Joint positions (rad), shape (2,).
        velocity: Joint velocities (rad/s), shape (2,), or None when absent.
        effort: Applied joint torques (N m), shape (2,), or None when absent.
    """

    stamp_ns: int
    position: FloatArray
    velocity: FloatArray | None = None
    effort: FloatArray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp_ns", _checked_stamp_ns(self.stamp_ns))
        for field in ("position", "velocity", "effort"):
            raw = getattr(self, field)
            if raw is None and field != "position":
                continue
            values = _frozen_copy(raw, field)
            _require_shape(values, TORQUE_SHAPE, field)
            object.__setattr__(self, field, values)


@dataclass(frozen=True, eq=False)
class StampedArray:
    """An array tied to the measurement it answers (torque command, reference).

    Attributes:
        stamp_ns: Stamp of the answered measurement (ns).
        values: Read-only float64 array, finite (shape (2,) for a torque, (3, 2) for a reference).
    """

    stamp_ns: int
    values: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp_ns", _checked_stamp_ns(self.stamp_ns))
        object.__setattr__(self, "values", _frozen_copy(self.values, "values"))


@dataclass(frozen=True, eq=False)
class LabelledArray:
    """Rows of named per-joint quantities tied to the measurement they answer.

    Attributes:
        stamp_ns: Stamp of the answered measurement (ns).
        row_labels: Name of each row, unique.
        values: Read-only float64 array, finite, shape (len(row_labels), 2), columns (alpha, beta).
    """

    stamp_ns: int
    row_labels: tuple[str, ...]
    values: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "stamp_ns", _checked_stamp_ns(self.stamp_ns))
        object.__setattr__(self, "row_labels", tuple(self.row_labels))
        _checked_axis_label(QUANTITY_DIM, self.row_labels)
        values = _frozen_copy(self.values, "values")
        _require_shape(values, (len(self.row_labels), NUM_JOINTS), "values")
        object.__setattr__(self, "values", values)

    def row(self, label: str) -> FloatArray:
        """Return the row named ``label``, shape (2,) (read-only view).

        Raises:
            KeyError: no row has that name.
        """
        try:
            index = self.row_labels.index(label)
        except ValueError:
            raise KeyError(f"no row {label!r}; rows are {self.row_labels}") from None
        row: FloatArray = self.values[index]
        return row

    def as_dict(self) -> dict[str, FloatArray]:
        """Return ``{row label: row}`` in row order, each row shape (2,) (read-only views)."""
        return dict(zip(self.row_labels, self.values, strict=True))


# -------------------------------------------------------------------------------------- JointState


def _joint_order(names: Sequence[str]) -> list[int] | None:
    """Return the index of each of JOINT_NAMES in ``names`` (None if already in order)."""
    if names == _JOINT_NAME_LIST:
        return None
    name_list = list(names)
    duplicates = sorted({name for name in name_list if name_list.count(name) > 1})
    if duplicates:
        raise JointNameError(f"duplicate joint name(s) {duplicates} in {name_list}")
    unknown = [name for name in name_list if name not in JOINT_NAMES]
    if unknown:
        raise JointNameError(f"unknown joint name(s) {unknown} in {name_list}; SMM joints are {JOINT_NAMES}")
    missing = [name for name in JOINT_NAMES if name not in name_list]
    if missing:
        raise JointNameError(f"missing joint(s) {missing} in {name_list}; SMM joints are {JOINT_NAMES}")
    return [name_list.index(name) for name in JOINT_NAMES]


def _joint_field(
    values: Sequence[float], count: int, field: str, required: bool, order: list[int] | None
) -> FloatArray | None:
    """Return the field reordered into JOINT_NAMES order (a view when already in order), None if absent."""
    length = len(values)
    if length == 0:
        if required:
            raise ArrayLengthError(f"JointState.{field} is empty but required")
        return None
    if length != count:
        raise ArrayLengthError(f"JointState.{field} has {length} values for {count} names")
    as_array = np.asarray(values, dtype=np.float64)
    return as_array if order is None else as_array[order]


def joint_state_to_sample(
    msg: JointState, require_velocity: bool = False, require_effort: bool = False
) -> JointSample:
    """Convert a ``sensor_msgs/JointState`` to a :class:`JointSample` in (alpha, beta) order.

    Joints may come in any order. Following the JointState convention an empty ``velocity`` or ``effort``
    means absent; a non-empty one must have one value per name. ``position`` is always required.

    Args:
        msg: The message.
        require_velocity: Reject a message without velocities (e.g. TD output, ground truth).
        require_effort: Reject a message without efforts (e.g. raw measurement: effort = applied torque).

    Returns:
        The sample; ``stamp_ns`` is ``header.stamp`` in ns.

    Raises:
        JointNameError: unknown, missing or duplicate joint names.
        ArrayLengthError: a field's length differs from the number of names, or a required field is empty.
        NonFiniteError: NaN or Inf in a field.
        StampError: invalid ``header.stamp``.
    """
    names = msg.name
    order = _joint_order(names)
    count = len(names)
    return JointSample(
        stamp_ns=stamp_to_ns(msg.header.stamp),
        position=_joint_field(msg.position, count, "position", True, order),  # type: ignore[arg-type]
        velocity=_joint_field(msg.velocity, count, "velocity", require_velocity, order),
        effort=_joint_field(msg.effort, count, "effort", require_effort, order),
    )


def _double_buffer(values: FloatArray | None) -> array.array[float]:
    """Return ``values`` as the ``array.array('d')`` rclpy stores double sequences in (no per-item check)."""
    return array.array("d") if values is None else array.array("d", values.tobytes())


def sample_to_joint_state(sample: JointSample) -> JointState:
    """Convert a :class:`JointSample` to a ``sensor_msgs/JointState``.

    Args:
        sample: The (already validated) sample.

    Returns:
        JointState with ``header.stamp`` = ``sample.stamp_ns``, ``frame_id`` "", names (alpha, beta), and
        empty ``velocity`` / ``effort`` when the sample has none.
    """
    msg = JointState()
    msg.header.stamp = ns_to_stamp(sample.stamp_ns)
    msg.name = list(JOINT_NAMES)
    msg.position = _double_buffer(sample.position)
    msg.velocity = _double_buffer(sample.velocity)
    msg.effort = _double_buffer(sample.effort)
    return msg


# ----------------------------------------------------------------------------- labelled multi-arrays


def _dim_label(dim_name: str, items: Sequence[str]) -> str:
    return dim_name + DIM_SEPARATOR + ITEM_SEPARATOR.join(items)


@functools.lru_cache(maxsize=256)
def _checked_axis_label(dim_name: str, items: tuple[str, ...]) -> str:
    """Validate item names (non-empty, unique, no separator or whitespace) and return the dimension label."""
    if not items:
        raise ArrayLengthError(f"dimension {dim_name!r} needs at least one item")
    for item in items:
        if not isinstance(item, str) or not item or any(c in _FORBIDDEN_IN_ITEM or c.isspace() for c in item):
            raise LayoutError(f"dimension {dim_name!r}: bad item name {item!r} (non-empty, no ':' ',' space)")
    if len(set(items)) != len(items):
        raise LayoutError(f"dimension {dim_name!r}: duplicate item names in {items}")
    return _dim_label(dim_name, items)


@functools.lru_cache(maxsize=256)
def _parse_axis_label(label: str, dim_name: str) -> tuple[str, ...]:
    """Return the item names of a ``<dim_name>:<items>`` label, or raise LayoutError."""
    head, separator, tail = label.partition(DIM_SEPARATOR)
    if not separator or head != dim_name:
        raise LayoutError(f"dimension label {label!r} does not start with {dim_name + DIM_SEPARATOR!r}")
    items = tuple(tail.split(ITEM_SEPARATOR))
    try:
        _checked_axis_label(dim_name, items)
    except ArrayLengthError as error:  # an empty item list is a malformed label here, not a short array
        raise LayoutError(str(error)) from error
    return items


def _parse_stamp_label(label: str) -> int:
    head, separator, digits = label.partition(DIM_SEPARATOR)
    if not separator or head != STAMP_DIM:
        raise LayoutError(f"last dimension label {label!r} is not {_STAMP_PREFIX}<int> (missing stamp?)")
    # Canonical decimal only: int() would also take '+5', ' 5', '1_0' and non-ASCII digits.
    if not (digits.isascii() and digits.isdigit()) or (len(digits) > 1 and digits[0] == "0"):
        raise StampError(f"stamp label {label!r}: {digits!r} is not a canonical non-negative integer")
    return _checked_stamp_ns(int(digits))


def _encode(values: FloatArray, axis_labels: Sequence[str], stamp_ns: int) -> Float64MultiArray:
    """Build the message of a validated array whose axes carry ``axis_labels``, plus the stamp dimension."""
    stamp_label = _STAMP_PREFIX + str(_checked_stamp_ns(stamp_ns))
    dims = []
    stride = values.size
    for label, size in zip(axis_labels, values.shape, strict=True):
        dims.append(MultiArrayDimension(label=label, size=size, stride=stride))
        stride //= size
    dims.append(MultiArrayDimension(label=stamp_label, size=1, stride=1))
    msg = Float64MultiArray()
    msg.layout.dim = dims
    msg.layout.data_offset = 0
    msg.data = array.array("d", values.tobytes())
    return msg


def _decode(
    msg: Float64MultiArray, axes: Sequence[_Axis], what: str
) -> tuple[int, list[tuple[str, ...]], FloatArray]:
    """Check the layout of ``msg`` against ``axes`` + stamp; return (stamp_ns, items per axis, data view)."""
    layout = msg.layout
    if layout.data_offset != 0:
        raise LayoutError(f"{what}: data_offset is {layout.data_offset}, must be 0")
    dims = layout.dim
    if len(dims) != len(axes) + 1:
        labels = [dim.label for dim in dims]
        raise LayoutError(f"{what}: dimensions {labels}, expected {len(axes)} + '{_STAMP_PREFIX}<int>'")
    items_per_axis: list[tuple[str, ...]] = []
    for dim, axis in zip(dims, axes, strict=False):  # dims has one more: the stamp
        if axis.items is None:
            items = _parse_axis_label(dim.label, axis.name)
        elif dim.label == axis.label:
            items = axis.items
        else:
            raise LayoutError(f"{what}: dimension label {dim.label!r}, expected {axis.label!r}")
        if dim.size != len(items):
            raise LayoutError(f"{what}: dimension {dim.label!r} has size {dim.size}, expected {len(items)}")
        items_per_axis.append(items)
    stamp_dim = dims[-1]
    stamp_ns = _parse_stamp_label(stamp_dim.label)
    if stamp_dim.size != 1 or stamp_dim.stride != 1:
        raise LayoutError(
            f"{what}: stamp dimension size {stamp_dim.size}, stride {stamp_dim.stride}; must be 1, 1"
        )
    expected_stride = 1
    for dim in reversed(dims[:-1]):
        expected_stride *= dim.size
        if dim.stride != expected_stride:
            raise LayoutError(
                f"{what}: dimension {dim.label!r} has stride {dim.stride}, expected {expected_stride}"
            )
    data = msg.data
    if len(data) != expected_stride:
        raise ArrayLengthError(f"{what}: {len(data)} data values, layout needs {expected_stride}")
    shape = tuple(len(items) for items in items_per_axis)
    return stamp_ns, items_per_axis, np.asarray(data, dtype=np.float64).reshape(shape)


def _fixed_axis(name: str, items: tuple[str, ...]) -> _Axis:
    return _Axis(name, items, _checked_axis_label(name, items))


_JOINT_AXIS: Final[_Axis] = _fixed_axis(JOINT_DIM, JOINT_NAMES)
_TORQUE_AXES: Final[tuple[_Axis, ...]] = (_JOINT_AXIS,)
_REFERENCE_AXES: Final[tuple[_Axis, ...]] = (_fixed_axis(ORDER_DIM, REFERENCE_ROWS), _JOINT_AXIS)
_TORQUE_LABELS: Final[tuple[str, ...]] = tuple(str(axis.label) for axis in _TORQUE_AXES)
_REFERENCE_LABELS: Final[tuple[str, ...]] = tuple(str(axis.label) for axis in _REFERENCE_AXES)


def _validated(values: npt.ArrayLike, shape: tuple[int, ...], field: str) -> FloatArray:
    checked = _frozen_copy(values, field)
    _require_shape(checked, shape, field)
    return checked


def torque_to_msg(tau: npt.ArrayLike, stamp_ns: int) -> Float64MultiArray:
    """Build a torque command: data = [tau_alpha, tau_beta] (N m), layout ``joint:alpha,beta`` + stamp.

    Args:
        tau: Joint torques (N m), shape (2,).
        stamp_ns: Stamp of the measurement this command answers (ns).

    Returns:
        The message; ``data`` is exactly the 2 torques (ros2_control forward-command convention).

    Raises:
        ArrayLengthError: shape is not (2,).
        NonFiniteError: NaN or Inf.
        StampError: invalid stamp.
    """
    return _encode(_validated(tau, TORQUE_SHAPE, "torque"), _TORQUE_LABELS, stamp_ns)


def msg_to_torque(msg: Float64MultiArray) -> StampedArray:
    """Parse a torque command.

    Args:
        msg: Message built by :func:`torque_to_msg` (or an equivalent publisher).

    Returns:
        ``StampedArray`` with values shape (2,) (N m) and the stamp of the answered measurement.

    Raises:
        LayoutError: wrong dimension count, labels, sizes, strides or data_offset, or missing stamp.
        ArrayLengthError: ``len(data)`` differs from the layout.
        NonFiniteError: NaN or Inf.
        StampError: malformed or out-of-range stamp.
    """
    stamp_ns, _, values = _decode(msg, _TORQUE_AXES, "torque command")
    return StampedArray(stamp_ns=stamp_ns, values=values)


def reference_to_msg(reference: npt.ArrayLike, stamp_ns: int) -> Float64MultiArray:
    """Build a reference message: 3x2, rows position/velocity/acceleration, columns alpha/beta.

    Args:
        reference: Shape (3, 2): position (rad), velocity (rad/s), acceleration (rad/s^2) per joint.
        stamp_ns: Stamp of the measurement this reference answers (ns).

    Returns:
        The message, layout ``order:position,velocity,acceleration`` (size 3, stride 6),
        ``joint:alpha,beta`` (2, 2), ``stamp_ns:<int>`` (1, 1).

    Raises:
        ArrayLengthError: shape is not (3, 2).
        NonFiniteError: NaN or Inf.
        StampError: invalid stamp.
    """
    return _encode(_validated(reference, REFERENCE_SHAPE, "reference"), _REFERENCE_LABELS, stamp_ns)


def msg_to_reference(msg: Float64MultiArray) -> StampedArray:
    """Parse a reference message.

    Returns:
        ``StampedArray`` with values shape (3, 2).

    Raises:
        LayoutError, ArrayLengthError, NonFiniteError, StampError: as :func:`msg_to_torque`.
    """
    stamp_ns, _, values = _decode(msg, _REFERENCE_AXES, "reference")
    return StampedArray(stamp_ns=stamp_ns, values=values)


def labelled_to_msg(
    values: npt.ArrayLike, row_labels: Sequence[str], stamp_ns: int, row_dim: str = QUANTITY_DIM
) -> Float64MultiArray:
    """Build a labelled array: rows = named quantities, columns = joints (alpha, beta).

    Args:
        values: Shape (n, 2), n = len(row_labels) >= 1; units are those of each quantity.
        row_labels: Unique row names (non-empty, without ':', ',' or whitespace), e.g. ``("xi_tilde",)``.
        stamp_ns: Stamp of the measurement these values answer (ns).
        row_dim: Name of the row dimension (``quantity``; ``order`` for a reference).

    Returns:
        The message, layout ``<row_dim>:<rows>`` (n, 2n), ``joint:alpha,beta`` (2, 2), ``stamp_ns:<int>``.

    Raises:
        ArrayLengthError: shape is not (len(row_labels), 2), or no rows.
        LayoutError: invalid or duplicate row labels.
        NonFiniteError: NaN or Inf.
        StampError: invalid stamp.
    """
    row_label = _checked_axis_label(row_dim, tuple(row_labels))
    checked = _validated(values, (len(row_labels), NUM_JOINTS), "values")
    return _encode(checked, (row_label, str(_JOINT_AXIS.label)), stamp_ns)


def msg_to_labelled(
    msg: Float64MultiArray, expected_rows: Sequence[str] | None = None, row_dim: str = QUANTITY_DIM
) -> LabelledArray:
    """Parse a labelled array.

    Args:
        msg: Message built by :func:`labelled_to_msg`.
        expected_rows: If given, the row labels must be exactly these, in this order.
        row_dim: Expected name of the row dimension.

    Returns:
        ``LabelledArray`` with values shape (n, 2).

    Raises:
        LayoutError: bad layout, or rows differing from ``expected_rows``.
        ArrayLengthError, NonFiniteError, StampError: as :func:`msg_to_torque`.
    """
    rows = None if expected_rows is None else tuple(expected_rows)
    row_axis = _Axis(row_dim) if rows is None else _fixed_axis(row_dim, rows)
    stamp_ns, items, values = _decode(msg, (row_axis, _JOINT_AXIS), "labelled array")
    return LabelledArray(stamp_ns=stamp_ns, row_labels=items[0], values=values)


def internals_to_msg(internals: Mapping[str, npt.ArrayLike], stamp_ns: int) -> Float64MultiArray:
    """Build a labelled array from an algorithm's ``internals`` mapping (one row per key, in mapping order).

    Args:
        internals: ``{name: per-joint values, shape (2,)}``, at least one entry.
        stamp_ns: Stamp of the measurement these values answer (ns).

    Returns:
        The message (see :func:`labelled_to_msg`).

    Raises:
        ArrayLengthError: an entry is not shape (2,), or the mapping is empty.
        LayoutError, NonFiniteError, StampError: as :func:`labelled_to_msg`.
    """
    rows = []
    for name, row in internals.items():
        rows.append(_validated(row, TORQUE_SHAPE, f"internals[{name!r}]"))
    if not rows:
        raise ArrayLengthError("internals: empty mapping, need at least one row")
    return labelled_to_msg(np.stack(rows), tuple(internals), stamp_ns)
