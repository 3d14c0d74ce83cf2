"""Stamps: integer ns <-> builtin_interfaces/Time, exact over the whole Time range, and /clock."""

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from hypothesis import given
from hypothesis import strategies as st

from smm_msgs_py import MAX_STAMP_NS, NANOSECONDS_PER_SECOND, StampError, clock_msg, ns_to_stamp, stamp_to_ns

INT32_MAX = 2**31 - 1


def test_max_stamp_is_the_largest_time() -> None:
    assert MAX_STAMP_NS == INT32_MAX * NANOSECONDS_PER_SECOND + 999_999_999
    stamp = ns_to_stamp(MAX_STAMP_NS)
    assert (stamp.sec, stamp.nanosec) == (INT32_MAX, 999_999_999)


@given(st.integers(min_value=0, max_value=MAX_STAMP_NS))
def test_ns_round_trip_is_exact(stamp_ns: int) -> None:
    stamp = ns_to_stamp(stamp_ns)
    assert 0 <= stamp.nanosec < NANOSECONDS_PER_SECOND
    assert stamp.sec * NANOSECONDS_PER_SECOND + stamp.nanosec == stamp_ns
    assert stamp_to_ns(stamp) == stamp_ns


@given(st.integers(min_value=0, max_value=INT32_MAX), st.integers(min_value=0, max_value=999_999_999))
def test_time_round_trip_is_exact(sec: int, nanosec: int) -> None:
    back = ns_to_stamp(stamp_to_ns(Time(sec=sec, nanosec=nanosec)))
    assert (back.sec, back.nanosec) == (sec, nanosec)


@pytest.mark.parametrize(
    "stamp_ns",
    [
        0,
        1,
        999_999_999,
        1_000_000_000,
        2**32,
        2**53 + 1,
        2**60 + 1,
        2**61 - 1 - 2**58,
        MAX_STAMP_NS - 1,
        MAX_STAMP_NS,
    ],
)
def test_boundary_stamps_round_trip(stamp_ns: int) -> None:
    assert stamp_to_ns(ns_to_stamp(stamp_ns)) == stamp_ns


def test_numpy_integer_stamp_is_accepted() -> None:
    assert stamp_to_ns(ns_to_stamp(np.int64(2**62 // 3))) == 2**62 // 3  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "stamp_ns",
    [-1, -(2**63), MAX_STAMP_NS + 1, (INT32_MAX + 1) * NANOSECONDS_PER_SECOND, 2**63 - 1, 2**63, 2**64],
)
def test_out_of_range_stamp_is_rejected(stamp_ns: int) -> None:
    with pytest.raises(StampError):
        ns_to_stamp(stamp_ns)


@pytest.mark.parametrize("stamp_ns", [1.0, True, "5", None, np.float64(3.0)])
def test_non_integer_stamp_is_rejected(stamp_ns: object) -> None:
    with pytest.raises(StampError):
        ns_to_stamp(stamp_ns)  # type: ignore[arg-type]


def test_negative_time_is_rejected() -> None:
    with pytest.raises(StampError, match="negative"):
        stamp_to_ns(Time(sec=-1, nanosec=999_999_999))


def test_unnormalised_nanosec_is_rejected() -> None:
    with pytest.raises(StampError, match="nanosec"):
        stamp_to_ns(Time(sec=0, nanosec=NANOSECONDS_PER_SECOND))


@given(st.integers(min_value=0, max_value=MAX_STAMP_NS))
def test_clock_msg_carries_the_stamp(stamp_ns: int) -> None:
    assert stamp_to_ns(clock_msg(stamp_ns).clock) == stamp_ns


def test_clock_msg_rejects_negative_stamp() -> None:
    with pytest.raises(StampError):
        clock_msg(-1)
