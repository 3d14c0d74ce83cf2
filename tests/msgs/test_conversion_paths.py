"""The conversions' fast path (finite float64 arrays, rclpy buffers) and generic path agree, errors keep
their precedence, results are complete and read-only, and no message object is shared between messages."""

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import pytest
from builtin_interfaces.msg import Time
from numpy.testing import assert_array_equal
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from smm_msgs_py import (
    OBSERVER_STATE_ROWS,
    ArrayLengthError,
    JointSample,
    LabelledArray,
    LayoutError,
    NonFiniteError,
    StampedArray,
    StampError,
    internals_to_msg,
    joint_state_to_sample,
    labelled_to_msg,
    msg_to_labelled,
    msg_to_reference,
    msg_to_torque,
    ns_to_stamp,
    reference_to_msg,
    sample_to_joint_state,
    torque_to_msg,
)

STAMP_NS = 1_700_000_000_123_456_789

# Small integers: exact in every dtype below, so each spelling holds the same float64 values.
REFERENCE = np.array([[5.0, -1.0], [2.0, 3.0], [-4.0, 0.0]])
Spelling = Callable[[np.ndarray], npt.ArrayLike]


def read_only(values: np.ndarray) -> np.ndarray:
    frozen = values.copy()
    frozen.flags.writeable = False
    return frozen


SPELLINGS: dict[str, Spelling] = {
    "float64": lambda a: a.copy(),
    "read-only float64": read_only,
    "list": lambda a: a.tolist(),
    "tuple": lambda a: tuple(map(tuple, a)) if a.ndim == 2 else tuple(a),
    "float32": lambda a: a.astype(np.float32),
    "big-endian": lambda a: a.astype(">f8"),
    "int": lambda a: a.astype(np.int64),
    "strided view": lambda a: np.repeat(a, 2, axis=-1)[..., ::2],
    "fortran order": np.asfortranarray,
    "masked array": np.ma.masked_array,
}


def layout_and_data(msg: Float64MultiArray) -> tuple[list[tuple[str, int, int]], int, list[float]]:
    dims = [(dim.label, dim.size, dim.stride) for dim in msg.layout.dim]
    return dims, msg.layout.data_offset, list(msg.data)


@pytest.mark.parametrize("spelling", sorted(SPELLINGS))
def test_every_input_type_gives_the_same_message(spelling: str) -> None:
    spell = SPELLINGS[spelling]
    torque, observer = REFERENCE[0], np.vstack([REFERENCE, REFERENCE[:1]])
    assert layout_and_data(torque_to_msg(spell(torque), STAMP_NS)) == layout_and_data(
        torque_to_msg(torque.tolist(), STAMP_NS)
    )
    assert layout_and_data(reference_to_msg(spell(REFERENCE), STAMP_NS)) == (
        [
            ("order:position,velocity,acceleration", 3, 6),
            ("joint:alpha,beta", 2, 2),
            (f"stamp_ns:{STAMP_NS}", 1, 1),
        ],
        0,
        REFERENCE.ravel().tolist(),
    )
    assert (
        list(labelled_to_msg(spell(observer), OBSERVER_STATE_ROWS, STAMP_NS).data)
        == observer.ravel().tolist()
    )
    internals = {name: spell(row) for name, row in zip("abc", REFERENCE, strict=True)}
    assert list(internals_to_msg(internals, STAMP_NS).data) == REFERENCE.ravel().tolist()


@pytest.mark.parametrize("spelling", sorted(SPELLINGS))
def test_every_input_type_gives_the_same_sample(spelling: str) -> None:
    spell = SPELLINGS[spelling]
    # JointSample accepts any array-like at run time (its fields are typed as the arrays it stores).
    sample = JointSample(STAMP_NS, spell(REFERENCE[0]), spell(REFERENCE[1]), None)  # type: ignore[arg-type]
    for values, expected in ((sample.position, REFERENCE[0]), (sample.velocity, REFERENCE[1])):
        assert type(values) is np.ndarray
        assert values.dtype == np.float64
        assert not values.flags.writeable
        assert_array_equal(values, expected)


@pytest.mark.parametrize("spelling", ["float64", "list", "float32", "big-endian", "strided view"])
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_every_input_type_is_checked_for_non_finite_values(spelling: str, bad: float) -> None:
    reference = REFERENCE.copy()
    reference[2, 1] = bad
    with pytest.raises(
        NonFiniteError, match=r"reference: non-finite value\(s\) \[.*\] at index \[\[2, 1\]\]"
    ):
        reference_to_msg(SPELLINGS[spelling](reference), STAMP_NS)
    with pytest.raises(NonFiniteError, match=r"torque: .* at index \[\[1\]\]"):
        torque_to_msg(SPELLINGS[spelling](reference[2]), STAMP_NS)


# ------------------------------------------------------------------------------------ error precedence


def test_internals_report_the_first_bad_row() -> None:
    nan_first = {"a": np.array([math.nan, 0.0]), "b": np.zeros(3)}
    with pytest.raises(NonFiniteError, match=r"internals\['a'\]"):
        internals_to_msg(nan_first, STAMP_NS)
    shape_first = {"a": np.zeros(3), "b": np.array([math.nan, 0.0])}
    with pytest.raises(ArrayLengthError, match=r"internals\['a'\]"):
        internals_to_msg(shape_first, STAMP_NS)


def test_values_are_checked_before_labels_and_labels_before_the_stamp() -> None:
    with pytest.raises(NonFiniteError):
        internals_to_msg({"bad label": np.array([math.inf, 0.0])}, -1)
    with pytest.raises(LayoutError):
        internals_to_msg({"bad label": np.zeros(2)}, -1)
    with pytest.raises(LayoutError):  # row labels first, then values, then the stamp
        labelled_to_msg(np.array([[math.inf, 0.0]]), ["bad label"], -1)
    with pytest.raises(NonFiniteError):
        labelled_to_msg(np.array([[math.inf, 0.0]]), ["ok"], -1)
    with pytest.raises(StampError):
        labelled_to_msg(np.zeros((1, 2)), ["ok"], -1)


def test_decode_reports_the_first_fault_in_the_documented_order() -> None:
    def faulty(mutate: Callable[[Float64MultiArray], None]) -> Float64MultiArray:
        msg = reference_to_msg(REFERENCE, STAMP_NS)
        mutate(msg)
        return msg

    def stride_and_stamp_label(msg: Float64MultiArray) -> None:
        msg.layout.dim[0].stride = 5
        msg.layout.dim[2].label = "stamp_ns:05"

    def stride_and_stamp_size(msg: Float64MultiArray) -> None:
        msg.layout.dim[0].stride = 5
        msg.layout.dim[2].size = 2

    def both_strides(msg: Float64MultiArray) -> None:
        msg.layout.dim[0].stride = 5
        msg.layout.dim[1].stride = 3

    def stride_and_data(msg: Float64MultiArray) -> None:
        msg.layout.dim[0].stride = 5
        msg.data = [math.nan]

    def data_length_and_value(msg: Float64MultiArray) -> None:
        msg.data = [math.nan] * 5

    def stamp_and_label(msg: Float64MultiArray) -> None:
        msg.layout.dim[2].label = "stamp_ns:x"
        msg.layout.dim[1].label = "joint:beta,alpha"

    with pytest.raises(StampError):
        msg_to_reference(faulty(stride_and_stamp_label))
    with pytest.raises(LayoutError, match="stamp dimension size 2"):
        msg_to_reference(faulty(stride_and_stamp_size))
    with pytest.raises(LayoutError, match=r"'joint:alpha,beta' has stride 3, expected 2"):
        msg_to_reference(faulty(both_strides))
    with pytest.raises(LayoutError, match="stride 5, expected 6"):
        msg_to_reference(faulty(stride_and_data))
    with pytest.raises(ArrayLengthError, match="5 data values, layout needs 6"):
        msg_to_reference(faulty(data_length_and_value))
    with pytest.raises(LayoutError, match="'joint:beta,alpha', expected 'joint:alpha,beta'"):
        msg_to_reference(faulty(stamp_and_label))


def test_joint_state_lengths_are_checked_before_values() -> None:
    msg = JointState()
    msg.header.stamp = ns_to_stamp(STAMP_NS)
    msg.name = ["beta", "alpha"]
    msg.position = [math.nan, 0.0]
    msg.effort = [1.0]
    with pytest.raises(ArrayLengthError, match="effort"):
        joint_state_to_sample(msg)
    msg.effort = [1.0, 2.0]
    # position[0] belongs to beta: index 1 in the (alpha, beta) order of the sample.
    with pytest.raises(NonFiniteError, match=r"position: non-finite value\(s\) \[nan\] at index \[\[1\]\]"):
        joint_state_to_sample(msg)


@pytest.mark.parametrize(("sec", "nanosec"), [(0, -1), (1.5, 0), (2**31, 0)])
def test_header_stamps_outside_the_time_range_are_rejected(sec: float, nanosec: int) -> None:
    msg = sample_to_joint_state(JointSample(STAMP_NS, REFERENCE[0]))
    joint_state_to_sample(msg)
    # check_fields=False: rclpy's optional field checks would refuse to build these stamps at all.
    msg.header.stamp = Time(sec=sec, nanosec=nanosec, check_fields=False)
    with pytest.raises(StampError):
        joint_state_to_sample(msg)


# ----------------------------------------------------------------------------- results and messages


def assert_complete_and_read_only(result: object) -> None:
    assert dataclasses.is_dataclass(result)
    assert set(vars(result)) == {field.name for field in dataclasses.fields(result)}
    assert type(vars(result)["stamp_ns"]) is int
    for value in vars(result).values():
        if isinstance(value, np.ndarray):
            assert value.dtype == np.float64
            assert not value.flags.writeable
            assert value.base is None or not value.base.flags.writeable


def test_parsed_results_are_complete_read_only_and_equal_to_constructed_ones() -> None:
    swapped = REFERENCE[:, ::-1]  # columns (beta, alpha)
    measurement = sample_to_joint_state(JointSample(STAMP_NS, swapped[0], swapped[1], swapped[2]))
    measurement.name = ["beta", "alpha"]
    sample = joint_state_to_sample(measurement, require_velocity=True, require_effort=True)
    assert_complete_and_read_only(sample)
    assert repr(sample) == repr(JointSample(STAMP_NS, REFERENCE[0], REFERENCE[1], REFERENCE[2]))
    reference = msg_to_reference(reference_to_msg(REFERENCE, STAMP_NS))
    assert_complete_and_read_only(reference)
    assert repr(reference) == repr(StampedArray(STAMP_NS, REFERENCE))
    torque = msg_to_torque(torque_to_msg(REFERENCE[0], STAMP_NS))
    assert_complete_and_read_only(torque)
    assert repr(torque) == repr(StampedArray(STAMP_NS, REFERENCE[0]))
    labelled = msg_to_labelled(
        labelled_to_msg(REFERENCE, ["a", "b", "c"], STAMP_NS), expected_rows=["a", "b", "c"]
    )
    assert_complete_and_read_only(labelled)
    assert repr(labelled) == repr(LabelledArray(STAMP_NS, ("a", "b", "c"), REFERENCE))


def test_parsed_fields_share_no_memory_with_each_other_or_the_message() -> None:
    msg = sample_to_joint_state(JointSample(STAMP_NS, REFERENCE[0], REFERENCE[1], REFERENCE[2]))
    sample = joint_state_to_sample(msg)
    arrays = [sample.position, sample.velocity, sample.effort]
    for index, first in enumerate(arrays):
        assert first is not None
        for second in arrays[index + 1 :]:
            assert second is not None
            assert not np.shares_memory(first, second)
    msg.velocity[0] = 99.0
    assert sample.velocity is not None
    assert sample.velocity[0] == REFERENCE[1, 0]


def test_messages_share_no_mutable_objects() -> None:
    builders: list[Callable[[], Float64MultiArray | JointState]] = [
        lambda: torque_to_msg(REFERENCE[0], STAMP_NS),
        lambda: reference_to_msg(REFERENCE, STAMP_NS),
        lambda: labelled_to_msg(REFERENCE, ["a", "b", "c"], STAMP_NS),
        lambda: internals_to_msg({"a": REFERENCE[0]}, STAMP_NS),
        lambda: sample_to_joint_state(JointSample(STAMP_NS, REFERENCE[0], None, REFERENCE[1])),
    ]
    for build in builders:
        first, second = build(), build()
        untouched = repr(second)
        assert repr(first) == untouched
        if isinstance(first, Float64MultiArray):
            first.layout.dim[0].size = 99
            first.layout.dim[-1].label = "stamp_ns:1"
            first.data[0] = 99.0
        else:
            first.header.stamp.sec = 1
            first.name[0] = "gamma"
            first.position[0] = 99.0
            first.effort[0] = 99.0
        assert repr(first) != untouched
        assert repr(second) == untouched
        assert repr(build()) == untouched


def test_sample_fields_are_copies_of_the_caller_arrays() -> None:
    position = REFERENCE[0].copy()
    sample = JointSample(STAMP_NS, position)
    position[0] = 99.0
    assert sample.position[0] == REFERENCE[0, 0]
    msg = sample_to_joint_state(sample)
    assert list(msg.velocity) == []
    assert list(msg.effort) == []
