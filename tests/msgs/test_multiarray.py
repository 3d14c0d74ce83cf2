"""Float64MultiArray <-> numpy: torque, reference, labelled arrays, the stamp dimension, every rejection."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from multiarray_mutations import (
    Mutation,
    drop_stamp,
    extra_dim,
    second_stamp,
    set_data,
    set_dim,
    set_offset,
    stamp_first,
)
from numpy.testing import assert_array_equal
from std_msgs.msg import Float64MultiArray

from smm_msgs_py import (
    DISTURBANCE_ESTIMATE_ROWS,
    MAX_STAMP_NS,
    OBSERVER_STATE_ROWS,
    ORDER_DIM,
    REFERENCE_ROWS,
    ArrayLengthError,
    InterfaceError,
    LayoutError,
    NonFiniteError,
    StampError,
    conversions,
    internals_to_msg,
    labelled_to_msg,
    msg_to_labelled,
    msg_to_reference,
    msg_to_torque,
    reference_to_msg,
    torque_to_msg,
)

finite = st.floats(allow_nan=False, allow_infinity=False, allow_subnormal=True)
stamps = st.integers(min_value=0, max_value=MAX_STAMP_NS)
row_names = st.lists(
    st.text(alphabet="abcdefghijklmnopqrstuvwxyz_0123456789", min_size=1, max_size=12),
    min_size=1,
    max_size=8,
    unique=True,
)

STAMP_NS = 1_234_000_567


def dims(msg: Float64MultiArray) -> list[tuple[str, int, int]]:
    return [(dim.label, dim.size, dim.stride) for dim in msg.layout.dim]


def test_reference_layout_is_exactly_the_documented_one() -> None:
    msg = reference_to_msg(np.arange(6.0).reshape(3, 2), 1234)
    assert dims(msg) == [
        ("order:position,velocity,acceleration", 3, 6),
        ("joint:alpha,beta", 2, 2),
        ("stamp_ns:1234", 1, 1),
    ]
    assert msg.layout.data_offset == 0
    assert list(msg.data) == [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]  # row-major: rows are orders


def test_torque_layout_is_exactly_the_two_torques() -> None:
    msg = torque_to_msg(np.array([1.5, -2.5]), 42)
    assert dims(msg) == [("joint:alpha,beta", 2, 2), ("stamp_ns:42", 1, 1)]
    assert list(msg.data) == [1.5, -2.5]


def test_labelled_layout() -> None:
    msg = labelled_to_msg(np.zeros((4, 2)), OBSERVER_STATE_ROWS, 7)
    assert dims(msg) == [
        ("quantity:x1_hat,x2_hat,x3_hat,bandwidth", 4, 8),
        ("joint:alpha,beta", 2, 2),
        ("stamp_ns:7", 1, 1),
    ]


@given(hnp.arrays(np.float64, (2,), elements=finite), stamps)
def test_torque_round_trip(tau: np.ndarray, stamp_ns: int) -> None:
    msg = torque_to_msg(tau, stamp_ns)
    assert math.prod(dim.size for dim in msg.layout.dim) == len(msg.data) == 2
    parsed = msg_to_torque(msg)
    assert parsed.stamp_ns == stamp_ns
    assert parsed.values.shape == (2,)
    assert_array_equal(parsed.values, tau)


@given(hnp.arrays(np.float64, (3, 2), elements=finite), stamps)
def test_reference_round_trip(reference: np.ndarray, stamp_ns: int) -> None:
    msg = reference_to_msg(reference, stamp_ns)
    assert math.prod(dim.size for dim in msg.layout.dim) == len(msg.data) == 6
    parsed = msg_to_reference(msg)
    assert parsed.stamp_ns == stamp_ns
    assert_array_equal(parsed.values, reference)


@given(st.data(), row_names, stamps)
def test_labelled_round_trip(data: st.DataObject, rows: list[str], stamp_ns: int) -> None:
    values = data.draw(hnp.arrays(np.float64, (len(rows), 2), elements=finite))
    msg = labelled_to_msg(values, rows, stamp_ns)
    assert math.prod(dim.size for dim in msg.layout.dim) == len(msg.data)
    parsed = msg_to_labelled(msg)
    assert parsed.stamp_ns == stamp_ns
    assert parsed.row_labels == tuple(rows)
    assert_array_equal(parsed.values, values)
    assert_array_equal(msg_to_labelled(msg, expected_rows=rows).values, values)
    for index, row in enumerate(rows):
        assert_array_equal(parsed.row(row), values[index])
        assert_array_equal(parsed.as_dict()[row], values[index])


def test_reference_parses_as_a_labelled_array_with_order_rows() -> None:
    reference = np.arange(6.0).reshape(3, 2)
    parsed = msg_to_labelled(reference_to_msg(reference, 9), row_dim=ORDER_DIM)
    assert parsed.row_labels == REFERENCE_ROWS
    assert_array_equal(parsed.row("acceleration"), [4.0, 5.0])


def test_internals_mapping_becomes_rows_in_order() -> None:
    internals = {"kp": np.array([1.0, 2.0]), "e": np.array([-0.5, 0.25])}
    parsed = msg_to_labelled(internals_to_msg(internals, 11))
    assert parsed.row_labels == ("kp", "e")
    assert_array_equal(parsed.values, [[1.0, 2.0], [-0.5, 0.25]])
    assert parsed.stamp_ns == 11


def test_parsed_values_are_read_only_copies() -> None:
    msg = torque_to_msg(np.array([1.0, 2.0]), 0)
    parsed = msg_to_torque(msg)
    msg.data[0] = 99.0
    assert parsed.values[0] == 1.0
    with pytest.raises(ValueError, match="read-only"):
        parsed.values[0] = 5.0


def test_row_lookup_of_unknown_label_raises_key_error() -> None:
    parsed = msg_to_labelled(labelled_to_msg(np.zeros((2, 2)), DISTURBANCE_ESTIMATE_ROWS, 0))
    with pytest.raises(KeyError, match="nope"):
        parsed.row("nope")


# ------------------------------------------------------------------------------------ the stamp tie


@given(st.integers(min_value=0, max_value=2**31 - 1), st.integers(min_value=0, max_value=999_999_999))
def test_command_answers_exactly_the_measurement_stamp(sec: int, nanosec: int) -> None:
    from builtin_interfaces.msg import Time

    from smm_msgs_py import stamp_to_ns

    measurement_ns = stamp_to_ns(Time(sec=sec, nanosec=nanosec))
    assert msg_to_torque(torque_to_msg(np.zeros(2), measurement_ns)).stamp_ns == measurement_ns
    assert msg_to_reference(reference_to_msg(np.zeros((3, 2)), measurement_ns)).stamp_ns == measurement_ns


@pytest.mark.parametrize("stamp_ns", [0, 2**53 + 1, MAX_STAMP_NS - 1, MAX_STAMP_NS])
def test_large_stamps_survive_exactly(stamp_ns: int) -> None:
    # Beyond 2**53 a float would round the stamp; the label keeps every digit.
    parsed = msg_to_torque(torque_to_msg(np.zeros(2), stamp_ns))
    assert type(parsed.stamp_ns) is int
    assert parsed.stamp_ns == stamp_ns


# ---------------------------------------------------------------------------------- encode rejections


@pytest.mark.parametrize("shape", [(3,), (1,), (2, 1), (1, 2), ()])
def test_torque_of_wrong_shape_is_not_published(shape: tuple[int, ...]) -> None:
    with pytest.raises(ArrayLengthError):
        torque_to_msg(np.zeros(shape), 0)


@pytest.mark.parametrize("shape", [(2, 3), (6,), (3, 2, 1), (4, 2)])
def test_reference_of_wrong_shape_is_not_published(shape: tuple[int, ...]) -> None:
    with pytest.raises(ArrayLengthError):
        reference_to_msg(np.zeros(shape), 0)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_values_are_not_published(bad: float) -> None:
    with pytest.raises(NonFiniteError):
        torque_to_msg(np.array([0.0, bad]), 0)
    reference = np.zeros((3, 2))
    reference[2, 1] = bad
    with pytest.raises(NonFiniteError):
        reference_to_msg(reference, 0)
    with pytest.raises(NonFiniteError):
        labelled_to_msg(np.array([[bad, 0.0]]), ["x"], 0)
    with pytest.raises(NonFiniteError):
        internals_to_msg({"x": np.array([0.0, bad])}, 0)


@pytest.mark.parametrize(
    ("stamp_ns", "message"),
    [
        (-1, r"^stamp_ns=-1 outside \[0, "),
        (MAX_STAMP_NS + 1, rf"^stamp_ns={MAX_STAMP_NS + 1} outside"),
        (2**63, r"^stamp_ns=\d+ outside"),
        (1.0, r"^stamp_ns must be an integer number of ns, got 1.0"),
        (True, r"^stamp_ns must be an integer number of ns, got True"),
    ],
)
def test_bad_stamps_are_not_published(stamp_ns: int, message: str) -> None:
    with pytest.raises(StampError, match=message):
        torque_to_msg(np.zeros(2), stamp_ns)


@pytest.mark.parametrize(
    ("values", "rows", "error"),
    [
        (np.zeros((2, 2)), ["a"], ArrayLengthError),
        (np.zeros((1, 3)), ["a"], ArrayLengthError),
        (np.zeros((0, 2)), [], ArrayLengthError),
        (np.zeros((2, 2)), ["a", "a"], LayoutError),
        (np.zeros((1, 2)), [""], LayoutError),
        (np.zeros((1, 2)), ["a,b"], LayoutError),
        (np.zeros((1, 2)), ["a:b"], LayoutError),
        (np.zeros((1, 2)), ["a b"], LayoutError),
    ],
)
def test_bad_labelled_arrays_are_not_published(
    values: np.ndarray, rows: list[str], error: type[InterfaceError]
) -> None:
    with pytest.raises(error):
        labelled_to_msg(values, rows, 0)


def test_bad_internals_are_not_published() -> None:
    with pytest.raises(ArrayLengthError, match="'k'"):
        internals_to_msg({"e": np.zeros(2), "k": np.zeros(3)}, 0)
    with pytest.raises(ArrayLengthError):
        internals_to_msg({}, 0)


# ---------------------------------------------------------------------------------- decode rejections

TORQUE_MUTATIONS: dict[str, tuple[Mutation, type[InterfaceError]]] = {
    "data_offset": (set_offset, LayoutError),
    "missing stamp": (drop_stamp, LayoutError),
    "stamp not last": (stamp_first, LayoutError),
    "extra dimension": (extra_dim, LayoutError),
    "two stamp dimensions": (second_stamp, LayoutError),
    "joint order swapped": (set_dim(0, label="joint:beta,alpha"), LayoutError),
    "unknown joint": (set_dim(0, label="joint:alpha,gamma"), LayoutError),
    "wrong dim name": (set_dim(0, label="joints:alpha,beta"), LayoutError),
    "no dim name": (set_dim(0, label="alpha,beta"), LayoutError),
    "joint size": (set_dim(0, size=3), LayoutError),
    "joint stride": (set_dim(0, stride=1), LayoutError),
    "stamp size": (set_dim(1, size=2), LayoutError),
    "stamp stride": (set_dim(1, stride=2), LayoutError),
    "stamp dim name": (set_dim(1, label="stamp:5"), LayoutError),
    "stamp negative": (set_dim(1, label="stamp_ns:-5"), StampError),
    "stamp plus sign": (set_dim(1, label="stamp_ns:+5"), StampError),
    "stamp leading zero": (set_dim(1, label="stamp_ns:05"), StampError),
    "stamp underscore": (set_dim(1, label="stamp_ns:1_000"), StampError),
    "stamp space": (set_dim(1, label="stamp_ns: 5"), StampError),
    "stamp empty": (set_dim(1, label="stamp_ns:"), StampError),
    "stamp float": (set_dim(1, label="stamp_ns:1.0"), StampError),
    "stamp non-ascii digit": (set_dim(1, label="stamp_ns:\u0663"), StampError),
    "stamp 2^63-1": (set_dim(1, label=f"stamp_ns:{2**63 - 1}"), StampError),
    "stamp beyond Time": (set_dim(1, label=f"stamp_ns:{MAX_STAMP_NS + 1}"), StampError),
    "data too short": (set_data([1.0]), ArrayLengthError),
    "data too long": (set_data([1.0, 2.0, 3.0]), ArrayLengthError),
    "NaN": (set_data([1.0, math.nan]), NonFiniteError),
    "Inf": (set_data([math.inf, 1.0]), NonFiniteError),
    "-Inf": (set_data([1.0, -math.inf]), NonFiniteError),
}


@pytest.mark.parametrize("case", sorted(TORQUE_MUTATIONS))
def test_bad_torque_messages_are_rejected(case: str) -> None:
    mutate, error = TORQUE_MUTATIONS[case]
    msg = torque_to_msg(np.array([1.0, 2.0]), STAMP_NS)
    msg_to_torque(msg)  # valid before the mutation
    mutate(msg)
    with pytest.raises(error):
        msg_to_torque(msg)


REFERENCE_MUTATIONS: dict[str, tuple[Mutation, type[InterfaceError]]] = {
    "data_offset": (set_offset, LayoutError),
    "missing stamp": (drop_stamp, LayoutError),
    "rows reordered": (set_dim(0, label="order:velocity,position,acceleration"), LayoutError),
    "row missing": (set_dim(0, label="order:position,velocity"), LayoutError),
    "row dim name": (set_dim(0, label="quantity:position,velocity,acceleration"), LayoutError),
    "row size": (set_dim(0, size=2), LayoutError),
    "row stride": (set_dim(0, stride=3), LayoutError),
    "joint size": (set_dim(1, size=3), LayoutError),
    "joint stride": (set_dim(1, stride=3), LayoutError),
    "stamp stride": (set_dim(2, stride=0), LayoutError),
    "stamp negative": (set_dim(2, label="stamp_ns:-1"), StampError),
    "data too short": (set_data([0.0] * 5), ArrayLengthError),
    "NaN": (set_data([0.0] * 5 + [math.nan]), NonFiniteError),
}


@pytest.mark.parametrize("case", sorted(REFERENCE_MUTATIONS))
def test_bad_reference_messages_are_rejected(case: str) -> None:
    mutate, error = REFERENCE_MUTATIONS[case]
    msg = reference_to_msg(np.zeros((3, 2)), STAMP_NS)
    msg_to_reference(msg)
    mutate(msg)
    with pytest.raises(error):
        msg_to_reference(msg)


def test_torque_is_not_a_reference_and_vice_versa() -> None:
    with pytest.raises(LayoutError):
        msg_to_reference(torque_to_msg(np.zeros(2), 0))
    with pytest.raises(LayoutError):
        msg_to_torque(reference_to_msg(np.zeros((3, 2)), 0))


LABELLED_MUTATIONS: dict[str, tuple[Mutation, type[InterfaceError]]] = {
    "missing stamp": (drop_stamp, LayoutError),
    "empty row list": (set_dim(0, label="quantity:"), LayoutError),
    "empty row name": (set_dim(0, label="quantity:a,,c"), LayoutError),
    "duplicate rows": (set_dim(0, label="quantity:a,a,c"), LayoutError),
    "row dim name": (set_dim(0, label="order:a,b,c"), LayoutError),
    "no separator": (set_dim(0, label="quantity"), LayoutError),
    "row count vs size": (set_dim(0, label="quantity:a,b"), LayoutError),
    "row stride": (set_dim(0, stride=5), LayoutError),
    "joint label": (set_dim(1, label="joint:alpha"), LayoutError),
    "data too long": (set_data([0.0] * 7), ArrayLengthError),
    "Inf": (set_data([0.0] * 5 + [math.inf]), NonFiniteError),
    "stamp garbage": (set_dim(2, label="stamp_ns:abc"), StampError),
}


@pytest.mark.parametrize("case", sorted(LABELLED_MUTATIONS))
def test_bad_labelled_messages_are_rejected(case: str) -> None:
    mutate, error = LABELLED_MUTATIONS[case]
    msg = labelled_to_msg(np.zeros((3, 2)), ["a", "b", "c"], STAMP_NS)
    msg_to_labelled(msg)
    mutate(msg)
    with pytest.raises(error):
        msg_to_labelled(msg)


def test_labelled_rows_must_match_expected_rows() -> None:
    msg = labelled_to_msg(np.zeros((2, 2)), ["a", "b"], 0)
    msg_to_labelled(msg, expected_rows=["a", "b"])
    with pytest.raises(LayoutError):
        msg_to_labelled(msg, expected_rows=["b", "a"])
    with pytest.raises(LayoutError):
        msg_to_labelled(msg, expected_rows=["a"])


def test_layouts_follow_the_ros_stride_rule_when_built_afresh() -> None:
    """Layouts are computed once and cached (the torque and reference ones at import): rebuild them here,
    so the rule itself is tested and not a layout computed before, against strides written out by hand."""
    conversions._labelled_layout.cache_clear()
    conversions._checked_axis_label.cache_clear()
    msg = labelled_to_msg(np.arange(8.0).reshape(4, 2), ["w", "x", "y", "z"], 7, row_dim="order")
    assert dims(msg) == [("order:w,x,y,z", 4, 8), ("joint:alpha,beta", 2, 2), ("stamp_ns:7", 1, 1)]
    parsed = msg_to_labelled(msg, row_dim="order")
    assert parsed.row_labels == ("w", "x", "y", "z")
    assert_array_equal(parsed.values, np.arange(8.0).reshape(4, 2))
    torque = conversions._Layout((("joint:alpha,beta", 2, 2),), (2,), 2, ("alpha", "beta"))
    reference = conversions._Layout(
        (("order:position,velocity,acceleration", 3, 6), ("joint:alpha,beta", 2, 2)),
        (3, 2),
        6,
        ("position", "velocity", "acceleration"),
    )
    for layout, built in (
        (torque, conversions._make_layout((("joint", ("alpha", "beta")),))),
        (reference, conversions._make_layout((("order", REFERENCE_ROWS), ("joint", ("alpha", "beta"))))),
    ):
        assert built == layout
        assert all(type(stride) is int for _, _, stride in built.dims)
    assert torque == conversions._TORQUE_LAYOUT
    assert reference == conversions._REFERENCE_LAYOUT
