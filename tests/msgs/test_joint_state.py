"""JointState <-> JointSample: reordering by name, absent fields, and every rejection."""

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numpy.testing import assert_array_equal
from sensor_msgs.msg import JointState

from smm_msgs_py import (
    JOINT_NAMES,
    MAX_STAMP_NS,
    ArrayLengthError,
    InterfaceError,
    JointNameError,
    JointSample,
    NonFiniteError,
    StampError,
    joint_state_to_sample,
    ns_to_stamp,
    sample_to_joint_state,
    stamp_to_ns,
)

finite_pairs = hnp.arrays(
    np.float64, (2,), elements=st.floats(allow_nan=False, allow_infinity=False, allow_subnormal=True)
)
stamps = st.integers(min_value=0, max_value=MAX_STAMP_NS)


def make_joint_state(
    names: Sequence[str],
    position: npt.ArrayLike,
    velocity: npt.ArrayLike = (),
    effort: npt.ArrayLike = (),
    stamp_ns: int = 1_500_000_000,
) -> JointState:
    msg = JointState()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.name = list(names)
    msg.position = np.asarray(position, dtype=np.float64).tolist()
    msg.velocity = np.asarray(velocity, dtype=np.float64).tolist()
    msg.effort = np.asarray(effort, dtype=np.float64).tolist()
    return msg


def valid_measurement() -> JointState:
    return make_joint_state(["alpha", "beta"], [0.1, 0.2], [], [3.0, 4.0])


@given(
    stamp_ns=stamps,
    position=finite_pairs,
    velocity=finite_pairs,
    effort=finite_pairs,
    names=st.permutations(JOINT_NAMES),
)
def test_any_joint_order_is_reordered_to_alpha_beta(
    stamp_ns: int, position: np.ndarray, velocity: np.ndarray, effort: np.ndarray, names: list[str]
) -> None:
    order = [JOINT_NAMES.index(name) for name in names]
    msg = make_joint_state(names, position[order], velocity[order], effort[order], stamp_ns)
    sample = joint_state_to_sample(msg, require_velocity=True, require_effort=True)
    assert sample.stamp_ns == stamp_ns
    assert_array_equal(sample.position, position)
    assert_array_equal(sample.velocity, velocity)
    assert_array_equal(sample.effort, effort)


@given(stamp_ns=stamps, position=finite_pairs, effort=finite_pairs)
def test_sample_round_trip_keeps_absent_fields_absent(
    stamp_ns: int, position: np.ndarray, effort: np.ndarray
) -> None:
    msg = sample_to_joint_state(JointSample(stamp_ns, position, None, effort))
    assert stamp_to_ns(msg.header.stamp) == stamp_ns
    assert msg.header.frame_id == ""
    assert list(msg.name) == list(JOINT_NAMES)
    assert len(msg.velocity) == 0
    back = joint_state_to_sample(msg, require_effort=True)
    assert back.velocity is None
    assert_array_equal(back.position, position)
    assert_array_equal(back.effort, effort)


def test_sample_arrays_are_read_only_copies_of_the_message() -> None:
    msg = valid_measurement()
    sample = joint_state_to_sample(msg)
    msg.position[0] = 99.0
    assert sample.position[0] == 0.1
    with pytest.raises(ValueError, match="read-only"):
        sample.position[0] = 1.0


def test_all_errors_are_interface_errors_and_value_errors() -> None:
    for error in (JointNameError, ArrayLengthError, NonFiniteError, StampError):
        assert issubclass(error, InterfaceError)
    assert issubclass(InterfaceError, ValueError)


@pytest.mark.parametrize(
    ("names", "position", "needle"),
    [
        (["alpha", "beta", "gamma"], [0.0, 0.0, 0.0], "gamma"),
        (["alpha", "gamma"], [0.0, 0.0], "gamma"),
        (["Alpha", "beta"], [0.0, 0.0], "Alpha"),
        (["alpha"], [0.0], "beta"),
        (["beta"], [0.0], "alpha"),
        ([], [], "missing"),
        (["alpha", "alpha"], [0.0, 0.0], "duplicate"),
        (["alpha", "beta", "beta"], [0.0, 0.0, 0.0], "duplicate"),
    ],
)
def test_bad_joint_names_are_rejected_with_a_clear_message(
    names: list[str], position: list[float], needle: str
) -> None:
    with pytest.raises(JointNameError, match=needle):
        joint_state_to_sample(make_joint_state(names, position))


@pytest.mark.parametrize(
    ("position", "velocity", "effort"),
    [
        ([0.0], [], []),
        ([0.0, 0.0, 0.0], [], []),
        ([], [], []),
        ([0.0, 0.0], [1.0], []),
        ([0.0, 0.0], [1.0, 1.0, 1.0], []),
        ([0.0, 0.0], [], [1.0]),
    ],
)
def test_wrong_field_lengths_are_rejected(
    position: list[float], velocity: list[float], effort: list[float]
) -> None:
    with pytest.raises(ArrayLengthError, match="JointState"):
        joint_state_to_sample(make_joint_state(["alpha", "beta"], position, velocity, effort))


def test_required_velocity_must_be_present() -> None:
    msg = valid_measurement()
    joint_state_to_sample(msg)
    with pytest.raises(ArrayLengthError, match="velocity"):
        joint_state_to_sample(msg, require_velocity=True)


def test_required_effort_must_be_present() -> None:
    msg = make_joint_state(["alpha", "beta"], [0.0, 0.0], [1.0, 1.0], [])
    joint_state_to_sample(msg, require_velocity=True)
    with pytest.raises(ArrayLengthError, match="effort"):
        joint_state_to_sample(msg, require_effort=True)


@pytest.mark.parametrize("field", ["position", "velocity", "effort"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("names", [["alpha", "beta"], ["beta", "alpha"]])
def test_non_finite_values_are_rejected(field: str, bad: float, names: list[str]) -> None:
    values = {"position": [0.0, 0.0], "velocity": [0.0, 0.0], "effort": [0.0, 0.0]}
    values[field][1] = bad
    msg = make_joint_state(names, values["position"], values["velocity"], values["effort"])
    with pytest.raises(NonFiniteError, match=field):
        joint_state_to_sample(msg)


def test_negative_header_stamp_is_rejected() -> None:
    msg = valid_measurement()
    msg.header.stamp.sec = -1
    with pytest.raises(StampError):
        joint_state_to_sample(msg)


def test_unnormalised_header_stamp_is_rejected() -> None:
    msg = valid_measurement()
    msg.header.stamp.nanosec = 1_000_000_000
    with pytest.raises(StampError):
        joint_state_to_sample(msg)


@pytest.mark.parametrize("field", ["position", "velocity", "effort"])
@pytest.mark.parametrize("shape", [(1,), (3,), (2, 1), ()])
def test_sample_rejects_wrong_shapes(field: str, shape: tuple[int, ...]) -> None:
    arrays = {"position": np.zeros(2), "velocity": np.zeros(2), "effort": np.zeros(2)}
    JointSample(0, **arrays)
    arrays[field] = np.zeros(shape)
    with pytest.raises(ArrayLengthError, match=field):
        JointSample(0, **arrays)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_sample_rejects_non_finite_before_publishing(bad: float) -> None:
    with pytest.raises(NonFiniteError):
        sample_to_joint_state(JointSample(0, np.array([0.0, bad])))


@pytest.mark.parametrize("stamp_ns", [-1, MAX_STAMP_NS + 1, 1.5])
def test_sample_rejects_bad_stamps(stamp_ns: int) -> None:
    with pytest.raises(StampError):
        JointSample(stamp_ns, np.zeros(2))


@pytest.mark.parametrize("order", [("alpha", "beta"), ("beta", "alpha")])
def test_names_in_any_sequence_type_reorder_the_same(order: tuple[str, str]) -> None:
    """rclpy keeps ``name`` as assigned (a tuple stays a tuple): the names are matched by value, not type."""
    values = {"alpha": (0.1, 0.3, 0.5), "beta": (0.2, 0.4, 0.6)}  # position, velocity, effort of each joint
    msg = make_joint_state(list(order), *[[values[name][i] for name in order] for i in range(3)])
    msg.name = tuple(order)
    sample = joint_state_to_sample(msg)
    assert_array_equal(sample.position, [0.1, 0.2])
    assert_array_equal(sample.velocity, [0.3, 0.4])
    assert_array_equal(sample.effort, [0.5, 0.6])
