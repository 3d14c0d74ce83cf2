"""Bulk decoding (byte template per group, numpy views) gives exactly what decoding one by one gives."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from smm_bag.bulk import decode_arrays, decode_joint_states
from smm_bag.cdr import (
    decode_float64_multi_array,
    decode_joint_state,
    encode_float64_multi_array,
    encode_joint_state,
)

floats = st.floats(allow_nan=False, allow_infinity=False, allow_subnormal=False, width=64)
stamps = st.integers(0, 10**13)


@given(
    st.lists(
        st.tuples(
            stamps, st.sampled_from([("alpha", "beta"), ("beta", "alpha")]), floats, floats, st.booleans()
        ),
        min_size=1,
        max_size=30,
    )
)
def test_joint_states(items: list[tuple[int, tuple[str, str], float, float, bool]]) -> None:
    buffers = [
        encode_joint_state(stamp, list(names), [a, b], [], [b, a] if effort else [])
        for stamp, names, a, b, effort in items
    ]
    seen = set()
    for indices, columns in decode_joint_states(buffers):
        for row, index in enumerate(indices):
            expected = decode_joint_state(buffers[index])
            assert columns.stamps[row] == expected.stamp_ns and columns.names == expected.name
            assert tuple(columns.position[row]) == expected.position
            assert (tuple(columns.effort[row]) if columns.effort is not None else ()) == expected.effort
            seen.add(index)
    assert seen == set(range(len(buffers)))


@given(
    st.lists(
        st.tuples(stamps, st.lists(floats, min_size=2, max_size=2), st.booleans()), min_size=1, max_size=40
    )
)
def test_stamped_arrays_with_any_stamp_digits(items: list[tuple[int, list[float], bool]]) -> None:
    buffers = []
    for stamp, values, labelled in items:
        dims = [("quantity:x", 1, 2)] if labelled else []
        buffers.append(
            encode_float64_multi_array(
                [*dims, ("joint:alpha,beta", 2, 2), (f"stamp_ns:{stamp}", 1, 1)], values
            )
        )
    seen = set()
    for indices, columns in decode_arrays(buffers):
        for row, index in enumerate(indices):
            expected = decode_float64_multi_array(buffers[index])
            assert columns.stamps[row] == expected.stamp_ns
            assert columns.labels == (*(label for label, _, _ in expected.dims[:-1]), "stamp_ns:")
            np.testing.assert_array_equal(columns.data[row], expected.data)
            seen.add(index)
    assert seen == set(range(len(buffers)))
