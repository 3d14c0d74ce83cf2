"""JointSample, StampedArray and LabelledArray normalise what they are built from (issue #16).

Built directly (not through a conversion), each stores its stamp as a Python int and every array as a
read-only float64 copy, so later mutation of the caller's objects cannot reach a stored sample.
"""

from __future__ import annotations

import numpy as np
import pytest
from smm_msgs_py.conversions import JointSample, LabelledArray, StampedArray
from smm_msgs_py.errors import ArrayLengthError


def assert_frozen_float64(array: object, expected: list[object]) -> None:
    assert type(array) is np.ndarray
    assert array.dtype == np.float64
    assert not array.flags.writeable
    assert array.tolist() == expected


def test_joint_sample_normalises_every_field() -> None:
    position, velocity, effort = [1, 2], np.array([0.5, -0.5]), (3, 4)
    sample = JointSample(np.int64(7), position, velocity, effort)  # type: ignore[arg-type]
    assert type(sample.stamp_ns) is int and sample.stamp_ns == 7
    assert_frozen_float64(sample.position, [1.0, 2.0])
    assert_frozen_float64(sample.velocity, [0.5, -0.5])
    assert_frozen_float64(sample.effort, [3.0, 4.0])
    velocity[0] = 9.0
    assert sample.velocity is not None and sample.velocity[0] == 0.5


def test_stamped_array_normalises_every_field() -> None:
    values = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    stamped = StampedArray(np.uint32(9), values)  # type: ignore[arg-type]
    assert type(stamped.stamp_ns) is int and stamped.stamp_ns == 9
    assert_frozen_float64(stamped.values, [[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    values[0, 0] = -1.0
    assert stamped.values[0, 0] == 1.0
    with pytest.raises(ArrayLengthError, match=r"^values: not a rectangular array of numbers"):
        StampedArray(1, [[1.0, 2.0], [3.0]])  # type: ignore[arg-type]


def test_labelled_array_normalises_every_field() -> None:
    labelled = LabelledArray(np.int16(3), ["kp", "kd"], [[1, 2], [3, 4]])  # type: ignore[arg-type]
    assert type(labelled.stamp_ns) is int and labelled.stamp_ns == 3
    assert labelled.row_labels == ("kp", "kd")
    assert_frozen_float64(labelled.values, [[1.0, 2.0], [3.0, 4.0]])
    assert list(labelled.as_dict()) == ["kp", "kd"]
    assert labelled.as_dict()["kd"].tolist() == [3.0, 4.0]
