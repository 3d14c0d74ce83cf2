"""Message <-> numpy conversions of the SMM interface, validating both ways.

Layout and stamp rule (``stamp_ns:<int>`` as the last dimension): docs/INTERFACES.md. Converting to a
message validates shape, NaN/Inf and stamp; converting from one raises an
:class:`~smm_msgs_py.errors.InterfaceError` subclass.
"""

from __future__ import annotations

import array
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final, NamedTuple, TypeVar

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
_REVERSED_JOINT_NAME_LIST: Final[list[str]] = _JOINT_NAME_LIST[::-1]
_REVERSED_JOINT_ORDER: Final[list[int]] = list(range(NUM_JOINTS))[::-1]
_FORBIDDEN_IN_ITEM: Final[frozenset[str]] = frozenset((DIM_SEPARATOR, ITEM_SEPARATOR))
_FLOAT64: Final[np.dtype[np.float64]] = np.dtype(np.float64)
_LABELLED_AXES: Final[int] = 2  # rows (named quantities) and joints

_isfinite = math.isfinite
_Result = TypeVar("_Result")


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


def _set_stamp(stamp: Time, stamp_ns: int) -> None:
    """Write the checked ``stamp_ns`` into ``stamp`` (fresh, owned by a message we build) as sec, nanosec."""
    # Filling the Time the message constructor made costs half of building and assigning another one.
    stamp.sec, stamp.nanosec = divmod(_checked_stamp_ns(stamp_ns), NANOSECONDS_PER_SECOND)


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
    stamp = Time()
    _set_stamp(stamp, stamp_ns)
    return stamp


def clock_msg(stamp_ns: int) -> Clock:
    """Build the ``rosgraph_msgs/Clock`` the simulator publishes on ``/clock``.

    Args:
        stamp_ns: Simulation time in ns.

    Returns:
        The Clock message.

    Raises:
        StampError: invalid stamp (see :func:`ns_to_stamp`).
    """
    msg = Clock()
    _set_stamp(msg.clock, stamp_ns)
    return msg


# ----------------------------------------------------------------------------------- validated arrays


def _frozen_copy(values: npt.ArrayLike, field: str) -> FloatArray:
    """Return a read-only float64 copy of ``values``; raise NonFiniteError on NaN/Inf."""
    if type(values) is np.ndarray and values.dtype is _FLOAT64:
        copied = values.copy(order="K")  # what np.array(values, dtype=np.float64) does, without its overhead
    else:
        try:
            copied = np.array(values, dtype=np.float64)
        except (TypeError, ValueError) as error:
            raise ArrayLengthError(f"{field}: not a rectangular array of numbers ({error})") from error
    # math.isfinite over a list is ~8x faster than np.isfinite(...).all() for the few values we carry.
    if not all(map(_isfinite, copied.ravel().tolist())):
        bad = np.argwhere(~np.isfinite(copied)).tolist()
        raise NonFiniteError(f"{field}: non-finite value(s) {copied[~np.isfinite(copied)]} at index {bad}")
    copied.setflags(write=False)
    return copied


def _require_shape(values: FloatArray, shape: tuple[int, ...], field: str) -> None:
    if values.shape != shape:
        raise ArrayLengthError(f"{field}: expected shape {shape}, got {values.shape}")


def _validated(values: npt.ArrayLike, shape: tuple[int, ...], field: str) -> FloatArray:
    checked = _frozen_copy(values, field)
    _require_shape(checked, shape, field)
    return checked


def _finite_float64_items(values: object, shape: tuple[int, ...]) -> list[float] | None:
    """Return the items (row-major) of a finite float64 ndarray of ``shape``; None for any other input."""
    if type(values) is np.ndarray and values.dtype is _FLOAT64 and values.shape == shape:
        items: list[float] = (values if len(shape) == 1 else values.ravel()).tolist()
        if all(map(_isfinite, items)):
            return items
    return None


def _checked_items(values: npt.ArrayLike, shape: tuple[int, ...], field: str) -> list[float]:
    """Return the items (row-major) of ``values`` after the checks of :func:`_validated`, with its errors."""
    items = _finite_float64_items(values, shape)
    if items is None:  # another input type, or a bad value: the generic path converts or names the error
        items = _validated(values, shape, field).ravel().tolist()
    return items


def _frozen_items(items: list[float], shape: tuple[int, ...]) -> FloatArray:
    """Return finite Python floats as a read-only float64 array of ``shape`` (product = ``len(items)``)."""
    frozen = np.array(items, dtype=np.float64)
    frozen.setflags(write=False)  # before reshaping, so that the base of a reshaped view is read-only too
    return frozen if len(shape) == 1 else frozen.reshape(shape)


def _prevalidated(cls: type[_Result], **fields: Any) -> _Result:
    """Build a frozen result dataclass from fields already validated and frozen, skipping ``__post_init__``.

    The conversions build fresh read-only arrays and checked stamps themselves; ``__post_init__`` would
    check and copy each array a second time. ``__init__`` of a frozen dataclass only sets the fields.
    """
    instance = object.__new__(cls)
    instance.__dict__.update(fields)
    return instance


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
        object.__setattr__(self, "position", _validated(self.position, TORQUE_SHAPE, "position"))
        if self.velocity is not None:
            object.__setattr__(self, "velocity", _validated(self.velocity, TORQUE_SHAPE, "velocity"))
        if self.effort is not None:
            object.__setattr__(self, "effort", _validated(self.effort, TORQUE_SHAPE, "effort"))


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
        values = _validated(self.values, (len(self.row_labels), NUM_JOINTS), "values")
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
    if names == _REVERSED_JOINT_NAME_LIST:
        return _REVERSED_JOINT_ORDER
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
    values: array.array[float], count: int, field: str, required: bool, order: list[int] | None
) -> list[float] | None:
    """Return the field's floats in JOINT_NAMES order, None if absent (finiteness is checked later).

    rclpy stores every double sequence of a message as an ``array.array('d')`` (its setters convert what
    is assigned), so ``tolist()`` gives Python floats.
    """
    length = len(values)
    if length == 0:
        if required:
            raise ArrayLengthError(f"JointState.{field} is empty but required")
        return None
    if length != count:
        raise ArrayLengthError(f"JointState.{field} has {length} values for {count} names")
    items: list[float] = values.tolist()
    return items if order is None else [items[index] for index in order]


def _frozen_joint_field(values: list[float] | None, field: str) -> FloatArray | None:
    """Return a field of :func:`_joint_field` as a checked read-only array (the JointSample checks)."""
    if values is None:
        return None
    # Floats of a field whose length matched the valid names: shape (2,) already, only finiteness is left.
    if all(map(_isfinite, values)):
        return _frozen_items(values, TORQUE_SHAPE)
    return _frozen_copy(values, field)  # raises NonFiniteError naming the field and the bad values


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
    stamp_ns = stamp_to_ns(msg.header.stamp)
    # Every length is checked before any value, as JointSample(...) of the fields would.
    position = _joint_field(msg.position, count, "position", True, order)
    velocity = _joint_field(msg.velocity, count, "velocity", require_velocity, order)
    effort = _joint_field(msg.effort, count, "effort", require_effort, order)
    return _prevalidated(
        JointSample,
        stamp_ns=_checked_stamp_ns(stamp_ns),
        position=_frozen_joint_field(position, "position"),
        velocity=_frozen_joint_field(velocity, "velocity"),
        effort=_frozen_joint_field(effort, "effort"),
    )


def sample_to_joint_state(sample: JointSample) -> JointState:
    """Convert a :class:`JointSample` to a ``sensor_msgs/JointState``.

    Args:
        sample: The (already validated) sample.

    Returns:
        JointState with ``header.stamp`` = ``sample.stamp_ns``, ``frame_id`` "", names (alpha, beta), and
        empty ``velocity`` / ``effort`` when the sample has none.
    """
    msg = JointState()  # its double sequences start as empty array.array('d'): absent fields stay so
    _set_stamp(msg.header.stamp, sample.stamp_ns)
    msg.name = list(JOINT_NAMES)
    # The setters store the floats as a new array.array('d'): the message shares nothing with the sample.
    msg.position = sample.position.tolist()
    if sample.velocity is not None:
        msg.velocity = sample.velocity.tolist()
    if sample.effort is not None:
        msg.effort = sample.effort.tolist()
    return msg


# ----------------------------------------------------------------------------- labelled multi-arrays


class _Layout(NamedTuple):
    """The data dimensions of a message type (the stamp dimension follows them), computed once."""

    dims: tuple[tuple[str, int, int], ...]  # (label, size, stride) of each data dimension, in order
    shape: tuple[int, ...]
    size: int  # number of data values
    rows: tuple[str, ...]  # items of the first dimension


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


def _make_layout(axes: Sequence[tuple[str, tuple[str, ...]]]) -> _Layout:
    """Return the layout of the axes ``(dimension name, item names)``, validating the item names."""
    labels = [_checked_axis_label(name, items) for name, items in axes]
    shape = tuple(len(items) for _, items in axes)
    size = math.prod(shape)
    dims = []
    stride = size
    for label, length in zip(labels, shape, strict=True):
        dims.append((label, length, stride))
        stride //= length
    return _Layout(tuple(dims), shape, size, axes[0][1])


@functools.lru_cache(maxsize=256)
def _labelled_layout(row_dim: str, rows: tuple[str, ...]) -> _Layout:
    """Return the layout ``<row_dim>:<rows>``, ``joint:alpha,beta``; raise as :func:`_checked_axis_label`."""
    return _make_layout(((row_dim, rows), (JOINT_DIM, JOINT_NAMES)))


_TORQUE_LAYOUT: Final[_Layout] = _make_layout(((JOINT_DIM, JOINT_NAMES),))
_REFERENCE_LAYOUT: Final[_Layout] = _labelled_layout(ORDER_DIM, REFERENCE_ROWS)


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


def _encode(items: list[float], layout: _Layout, stamp_ns: int) -> Float64MultiArray:
    """Build the message of validated row-major ``items`` with ``layout`` plus the stamp dimension."""
    stamp_label = _STAMP_PREFIX + str(_checked_stamp_ns(stamp_ns))
    # Fresh dimension objects every time: a message holds references, and its holder may mutate them.
    dims = []
    for label, size, stride in (*layout.dims, (stamp_label, 1, 1)):
        dim = MultiArrayDimension()  # setting the fields is cheaper than passing them to the constructor
        dim.label = label
        dim.size = size
        dim.stride = stride
        dims.append(dim)
    msg = Float64MultiArray()
    msg.layout.dim = dims  # data_offset keeps its default, 0
    msg.data = items  # the setter stores them as a new array.array('d')
    return msg


def _decode(
    msg: Float64MultiArray, layout: _Layout | None, row_dim: str, what: str
) -> tuple[int, _Layout, FloatArray]:
    """Check the layout of ``msg`` against ``layout`` + stamp; return (stamp_ns, layout, values).

    ``layout`` None: a labelled array whose row labels are read from its first dimension (``row_dim``).
    The checks run, and so report the first error, in this order: data_offset, dimension count, labels and
    sizes, stamp label, stamp size and stride, strides from the innermost dimension, data length, values.
    """
    msg_layout = msg.layout
    if msg_layout.data_offset != 0:
        raise LayoutError(f"{what}: data_offset is {msg_layout.data_offset}, must be 0")
    dims = msg_layout.dim
    axis_count = _LABELLED_AXES if layout is None else len(layout.dims)
    if len(dims) != axis_count + 1:
        labels = [dim.label for dim in dims]
        raise LayoutError(f"{what}: dimensions {labels}, expected {axis_count} + '{_STAMP_PREFIX}<int>'")
    if layout is None:
        layout = _labelled_layout(row_dim, _parse_axis_label(dims[0].label, row_dim))
    strides_match = True
    for dim, (label, size, stride) in zip(dims, layout.dims, strict=False):  # dims has one more: the stamp
        if dim.label != label:
            raise LayoutError(f"{what}: dimension label {dim.label!r}, expected {label!r}")
        if dim.size != size:
            raise LayoutError(f"{what}: dimension {dim.label!r} has size {dim.size}, expected {size}")
        strides_match = strides_match and dim.stride == stride
    stamp_dim = dims[-1]
    stamp_ns = _parse_stamp_label(stamp_dim.label)
    if stamp_dim.size != 1 or stamp_dim.stride != 1:
        raise LayoutError(
            f"{what}: stamp dimension size {stamp_dim.size}, stride {stamp_dim.stride}; must be 1, 1"
        )
    if not strides_match:
        for dim, (_, _, stride) in reversed(list(zip(dims, layout.dims, strict=False))):
            if dim.stride != stride:
                raise LayoutError(
                    f"{what}: dimension {dim.label!r} has stride {dim.stride}, expected {stride}"
                )
    data = msg.data  # an array.array('d'), as rclpy stores every double sequence
    if len(data) != layout.size:
        raise ArrayLengthError(f"{what}: {len(data)} data values, layout needs {layout.size}")
    items: list[float] = data.tolist()
    if all(map(_isfinite, items)):
        return stamp_ns, layout, _frozen_items(items, layout.shape)
    # A NaN/Inf: the generic check names the bad values and their (row, joint) index.
    return stamp_ns, layout, _frozen_copy(np.reshape(items, layout.shape), "values")


def _decode_stamped(msg: Float64MultiArray, layout: _Layout, what: str) -> StampedArray:
    stamp_ns, _, values = _decode(msg, layout, "", what)
    return _prevalidated(StampedArray, stamp_ns=stamp_ns, values=values)


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
    return _encode(_checked_items(tau, TORQUE_SHAPE, "torque"), _TORQUE_LAYOUT, stamp_ns)


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
    return _decode_stamped(msg, _TORQUE_LAYOUT, "torque command")


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
    return _encode(_checked_items(reference, REFERENCE_SHAPE, "reference"), _REFERENCE_LAYOUT, stamp_ns)


def msg_to_reference(msg: Float64MultiArray) -> StampedArray:
    """Parse a reference message.

    Returns:
        ``StampedArray`` with values shape (3, 2).

    Raises:
        LayoutError, ArrayLengthError, NonFiniteError, StampError: as :func:`msg_to_torque`.
    """
    return _decode_stamped(msg, _REFERENCE_LAYOUT, "reference")


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
    layout = _labelled_layout(row_dim, tuple(row_labels))
    return _encode(_checked_items(values, layout.shape, "values"), layout, stamp_ns)


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
    expected = None if expected_rows is None else _labelled_layout(row_dim, tuple(expected_rows))
    stamp_ns, layout, values = _decode(msg, expected, row_dim, "labelled array")
    return _prevalidated(LabelledArray, stamp_ns=stamp_ns, row_labels=layout.rows, values=values)


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
    items: list[float] = []
    # Algorithms' internals and node counters are float64 arrays of shape (2,): one pass, one check.
    for row in internals.values():
        if type(row) is not np.ndarray or row.dtype is not _FLOAT64 or row.shape != TORQUE_SHAPE:
            break
        items += row.tolist()
    else:
        if items and all(map(_isfinite, items)):
            return _encode(items, _labelled_layout(QUANTITY_DIM, tuple(internals)), stamp_ns)
    # Another row type or a bad value: convert and check row by row, so the first bad row is the one named.
    items = []
    for name, row in internals.items():
        items += _checked_items(row, TORQUE_SHAPE, f"internals[{name!r}]")
    if not items:
        raise ArrayLengthError("internals: empty mapping, need at least one row")
    return _encode(items, _labelled_layout(QUANTITY_DIM, tuple(internals)), stamp_ns)
