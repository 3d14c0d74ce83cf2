"""The fast CDR codecs of JointState and Float64MultiArray agree with rclpy's own (de)serialisation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from smm_bag.cdr import (
    decode_float64_multi_array,
    decode_joint_state,
    encode_float64_multi_array,
    encode_joint_state,
    stamp_of,
)
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from smm_bag import CorruptBagError

floats = st.floats(allow_nan=False, allow_infinity=False, allow_subnormal=False, width=64)
names = st.lists(
    st.text(st.characters(codec="ascii", min_codepoint=97, max_codepoint=122), min_size=1, max_size=7)
)


@given(
    stamp=st.integers(0, (2**31 - 1) * 10**9),
    name=names,
    values=st.lists(floats, max_size=4),
    effort=st.lists(floats, max_size=3),
    frame=st.text(st.characters(codec="ascii", min_codepoint=97, max_codepoint=122), max_size=5),
)
def test_joint_state_round_trip_against_rclpy(
    stamp: int, name: list[str], values: list[float], effort: list[float], frame: str
) -> None:
    data = encode_joint_state(stamp, name, values, [], effort, frame_id=frame)
    message = deserialize_message(data, JointState)
    assert message.header.stamp.sec * 10**9 + message.header.stamp.nanosec == stamp
    assert message.header.frame_id == frame and list(message.name) == name
    assert list(message.position) == values and list(message.effort) == effort
    # rclpy's bytes (with its trailing padding) decode to the same values.
    decoded = decode_joint_state(serialize_message(message))
    assert (decoded.stamp_ns, list(decoded.name), list(decoded.position)) == (stamp, name, values)
    assert list(decoded.effort) == effort and decoded.velocity == ()
    assert stamp_of("sensor_msgs/msg/JointState", data) == stamp


@given(
    labels=st.lists(
        st.text(st.characters(codec="ascii", min_codepoint=97, max_codepoint=122), max_size=9), max_size=3
    ),
    data=st.lists(floats, max_size=7),
    stamp=st.integers(0, 10**18),
)
def test_float64_multi_array_round_trip_against_rclpy(
    labels: list[str], data: list[float], stamp: int
) -> None:
    dims = [(label, index + 1, 7) for index, label in enumerate(labels)] + [(f"stamp_ns:{stamp}", 1, 1)]
    encoded = encode_float64_multi_array(dims, data)
    message = deserialize_message(encoded, Float64MultiArray)
    assert [(d.label, d.size, d.stride) for d in message.layout.dim] == dims
    assert list(message.data) == data
    reference = Float64MultiArray()
    reference.layout.dim = [MultiArrayDimension(label=a, size=s, stride=t) for a, s, t in dims]
    reference.data = data
    decoded = decode_float64_multi_array(serialize_message(reference))
    assert list(decoded.dims) == dims and list(decoded.data) == data
    assert decoded.stamp_ns == stamp == stamp_of("std_msgs/msg/Float64MultiArray", encoded)


def test_malformed_bytes_raise_corrupt_bag_error() -> None:
    good = encode_joint_state(5, ["alpha", "beta"], [1.0, 2.0])
    for bad in (b"", b"\x00\x01\x00\x00", b"\x07\x07\x00\x00" + good[4:], good[:-5]):
        with pytest.raises(CorruptBagError):
            decode_joint_state(bad)
    with pytest.raises(CorruptBagError):
        decode_float64_multi_array(encode_float64_multi_array([("joint:a", 1, 1)], [1.0])[:-3])
    assert np.isfinite(decode_joint_state(good).position).all()
