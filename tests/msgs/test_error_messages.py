"""Every rejection says what was wrong and where: the message kind, the field, dimension or argument, and
the offending value (users read these errors on a test bench; the error type alone does not say which
field to fix)."""

import math
import re
from collections.abc import Callable

import numpy as np
import pytest
from multiarray_mutations import Mutation, extra_dim, set_data, set_dim, set_offset
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from smm_msgs_py import (
    MAX_STAMP_NS,
    ArrayLengthError,
    JointNameError,
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
    torque_to_msg,
)

STAMP_NS = 42
STAMP_LABEL = f"stamp_ns:{STAMP_NS}"


def torque() -> Float64MultiArray:
    return torque_to_msg(np.array([1.0, 2.0]), STAMP_NS)


def reference() -> Float64MultiArray:
    return reference_to_msg(np.zeros((3, 2)), STAMP_NS)


def labelled() -> Float64MultiArray:
    return labelled_to_msg(np.zeros((2, 2)), ["a", "b"], STAMP_NS)


# (build, parse, mutation, error, the whole expected text). Texts are written out from the layout rule
# (docs/INTERFACES.md), not copied from the code: each names the message kind, the dimension and the value.
CASES: dict[str, tuple[Callable[[], Float64MultiArray], Callable[..., object], Mutation, type, str]] = {
    "torque data_offset": (
        torque,
        msg_to_torque,
        set_offset,
        LayoutError,
        "torque command: data_offset is 1, must be 0",
    ),
    "torque extra dimension": (
        torque,
        msg_to_torque,
        extra_dim,
        LayoutError,
        f"torque command: dimensions ['joint:alpha,beta', '{STAMP_LABEL}', 'extra:x'], "
        "expected 1 + 'stamp_ns:<int>'",
    ),
    "reference joint size": (
        reference,
        msg_to_reference,
        set_dim(1, size=3),
        LayoutError,
        "reference: dimension 'joint:alpha,beta' has size 3, expected 2",
    ),
    "reference row label": (
        reference,
        msg_to_reference,
        set_dim(0, label="order:position,velocity"),
        LayoutError,
        "reference: dimension label 'order:position,velocity', "
        "expected 'order:position,velocity,acceleration'",
    ),
    "reference row stride": (
        reference,
        msg_to_reference,
        set_dim(0, stride=5),
        LayoutError,
        "reference: dimension 'order:position,velocity,acceleration' has stride 5, expected 6",
    ),
    "reference stamp size": (
        reference,
        msg_to_reference,
        set_dim(2, size=2),
        LayoutError,
        "reference: stamp dimension size 2, stride 1; must be 1, 1",
    ),
    "labelled data length": (
        labelled,
        msg_to_labelled,
        set_data([0.0] * 3),
        ArrayLengthError,
        "labelled array: 3 data values, layout needs 4",
    ),
    "labelled dimension count": (
        labelled,
        msg_to_labelled,
        extra_dim,
        LayoutError,
        f"labelled array: dimensions ['quantity:a,b', 'joint:alpha,beta', '{STAMP_LABEL}', 'extra:x'], "
        "expected 2 + 'stamp_ns:<int>'",
    ),
    "labelled NaN": (
        labelled,
        msg_to_labelled,
        set_data([0.0, 0.0, math.nan, 0.0]),
        NonFiniteError,
        "values: non-finite value(s) [nan] at index [[1, 0]]",
    ),
    "reference Inf": (
        reference,
        msg_to_reference,
        set_data([0.0] * 5 + [-math.inf]),
        NonFiniteError,
        "values: non-finite value(s) [-inf] at index [[2, 1]]",
    ),
    "stamp dimension name": (
        torque,
        msg_to_torque,
        set_dim(1, label="stamp:5"),
        LayoutError,
        "last dimension label 'stamp:5' is not stamp_ns:<int> (missing stamp?)",
    ),
    "stamp leading zero": (
        torque,
        msg_to_torque,
        set_dim(1, label="stamp_ns:05"),
        StampError,
        "stamp label 'stamp_ns:05': '05' is not a canonical non-negative integer",
    ),
    # A second ':' belongs to the stamp text (split at the first ':'): a bad stamp, not a bad label.
    "stamp with a colon": (
        torque,
        msg_to_torque,
        set_dim(1, label="stamp_ns:1:2"),
        StampError,
        "stamp label 'stamp_ns:1:2': '1:2' is not a canonical non-negative integer",
    ),
    "stamp beyond Time": (
        torque,
        msg_to_torque,
        set_dim(1, label=f"stamp_ns:{MAX_STAMP_NS + 1}"),
        StampError,
        f"stamp_ns={MAX_STAMP_NS + 1} outside [0, {MAX_STAMP_NS}] (builtin_interfaces/Time range)",
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_message_rejections_name_the_kind_dimension_and_value(case: str) -> None:
    build, parse, mutate, error, text = CASES[case]
    msg = build()
    parse(msg)  # valid before the mutation
    mutate(msg)
    with pytest.raises(error, match=f"^{re.escape(text)}$"):
        parse(msg)


def exactly(text: str) -> str:
    return f"^{re.escape(text)}$"


def test_building_messages_names_the_argument() -> None:
    with pytest.raises(NonFiniteError, match=exactly("torque: non-finite value(s) [inf] at index [[1]]")):
        torque_to_msg([1.0, math.inf], STAMP_NS)
    with pytest.raises(ArrayLengthError, match=exactly("reference: expected shape (3, 2), got (2, 3)")):
        reference_to_msg(np.zeros((2, 3)), STAMP_NS)
    with pytest.raises(ArrayLengthError, match=exactly("values: expected shape (1, 2), got (2,)")):
        labelled_to_msg([1.0, 2.0], ["a"], STAMP_NS)
    with pytest.raises(ArrayLengthError, match=r"^torque: not a rectangular array of numbers \("):
        torque_to_msg([[1.0], [1.0, 2.0]], STAMP_NS)
    with pytest.raises(ArrayLengthError, match=exactly("internals: empty mapping, need at least one row")):
        internals_to_msg({}, STAMP_NS)
    # A float64 array of the wrong shape, alone: no valid row follows that would send it to the row checks.
    with pytest.raises(ArrayLengthError, match=exactly("internals['k']: expected shape (2,), got (3,)")):
        internals_to_msg({"k": np.zeros(3)}, STAMP_NS)


@pytest.mark.parametrize(
    ("stamp", "text"),
    [
        (1.5, "stamp_ns must be an integer number of ns, got 1.5"),
        (True, "stamp_ns must be an integer number of ns, got True"),
        (-1, f"stamp_ns=-1 outside [0, {MAX_STAMP_NS}] (builtin_interfaces/Time range)"),
        (np.int64(-3), f"stamp_ns=-3 outside [0, {MAX_STAMP_NS}] (builtin_interfaces/Time range)"),
    ],
)
def test_stamp_rejections_say_why(stamp: object, text: str) -> None:
    with pytest.raises(StampError, match=exactly(text)):
        ns_to_stamp(stamp)  # type: ignore[arg-type]
    with pytest.raises(StampError, match=exactly(text)):
        torque_to_msg([0.0, 0.0], stamp)  # type: ignore[arg-type]


def joint_state(**fields: object) -> JointState:
    msg = JointState()
    msg.header.stamp.sec = 1
    msg.name = ["alpha", "beta"]
    msg.position = [0.1, 0.2]
    msg.velocity = [0.3, 0.4]
    msg.effort = [0.5, 0.6]
    for name, value in fields.items():
        setattr(msg, name, value)
    return msg


@pytest.mark.parametrize("field", ["position", "velocity", "effort"])
def test_joint_state_errors_name_the_field(field: str) -> None:
    with pytest.raises(ArrayLengthError, match=exactly(f"JointState.{field} has 3 values for 2 names")):
        joint_state_to_sample(joint_state(**{field: [0.0, 0.0, 0.0]}))
    with pytest.raises(ArrayLengthError, match=exactly(f"JointState.{field} is empty but required")):
        joint_state_to_sample(
            joint_state(**{field: []}), require_velocity=field == "velocity", require_effort=field == "effort"
        )
    with pytest.raises(NonFiniteError, match=exactly(f"{field}: non-finite value(s) [nan] at index [[0]]")):
        joint_state_to_sample(joint_state(**{field: [0.0, math.nan]}, name=["beta", "alpha"]))


def test_joint_name_errors_list_only_the_offending_names() -> None:
    with pytest.raises(JointNameError, match=r"^unknown joint name\(s\) \['gamma'\] in \['alpha', 'gamma'\]"):
        joint_state_to_sample(joint_state(name=["alpha", "gamma"]))
    with pytest.raises(JointNameError, match=r"^duplicate joint name\(s\) \['beta'\] in \['beta', 'beta'\]"):
        joint_state_to_sample(joint_state(name=["beta", "beta"]))
    with pytest.raises(JointNameError, match=r"^missing joint\(s\) \['beta'\] in \['alpha'\]"):
        joint_state_to_sample(joint_state(name=["alpha"], position=[0.1], velocity=[], effort=[]))


def test_result_dataclasses_name_the_field() -> None:
    with pytest.raises(NonFiniteError, match=r"^values: non-finite value\(s\) \[nan\] at index \[\[0\]\]$"):
        StampedArray(STAMP_NS, np.array([math.nan, 0.0]))
    with pytest.raises(ArrayLengthError, match=exactly("values: expected shape (1, 2), got (2, 2)")):
        LabelledArray(STAMP_NS, ("a",), np.zeros((2, 2)))
    for field in ("position", "velocity", "effort"):
        fields = {"position": np.zeros(2), field: np.zeros(3)}
        with pytest.raises(ArrayLengthError, match=exactly(f"{field}: expected shape (2,), got (3,)")):
            JointSample(STAMP_NS, **fields)  # type: ignore[arg-type]
