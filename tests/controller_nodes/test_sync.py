"""Exact-time synchroniser (pure, no ROS)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_controller.sync import ExactTimeSynchronizer

INPUTS = ("state", "reference", "estimate")


def test_emits_only_when_every_input_of_a_stamp_is_present() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(INPUTS)
    assert sync.add("state", 5, "s5") is None
    assert sync.add("reference", 5, "r5") is None
    matched = sync.add("estimate", 5, "e5")
    assert matched is not None
    assert matched.stamp_ns == 5
    assert dict(matched.items) == {"state": "s5", "reference": "r5", "estimate": "e5"}
    assert sync.pending_stamps == ()
    assert sync.last_matched_ns == 5
    assert sync.dropped == 0


def test_inputs_of_different_stamps_do_not_match() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(("a", "b"))
    assert sync.add("a", 1, "a1") is None
    assert sync.add("b", 2, "b2") is None
    assert sync.pending_stamps == (1, 2)


def test_completing_a_stamp_drops_older_incomplete_ones_and_counts_them() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(("a", "b"))
    sync.add("a", 1, "a1")
    sync.add("a", 2, "a2")
    sync.add("a", 4, "a4")
    matched = sync.add("b", 3, "b3") or sync.add("a", 3, "a3")
    assert matched is not None and matched.stamp_ns == 3
    assert sync.dropped == 2  # stamps 1 and 2 can never be answered after 3
    assert sync.pending_stamps == (4,)  # newer pending stamps survive
    completed = sync.add("b", 4, "b4")
    assert completed is not None and dict(completed.items) == {"a": "a4", "b": "b4"}


def test_pending_stamps_are_bounded_oldest_dropped_first() -> None:
    sync: ExactTimeSynchronizer[int] = ExactTimeSynchronizer(("a", "b"), max_pending=3)
    for stamp in range(5):
        sync.add("a", stamp, stamp)
    assert sync.pending_stamps == (2, 3, 4)
    assert sync.dropped == 2


def test_inputs_not_newer_than_the_last_match_are_late_and_ignored() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(("a", "b"))
    sync.add("a", 7, "a7")
    assert sync.add("b", 7, "b7") is not None
    assert sync.add("a", 7, "again") is None
    assert sync.add("b", 6, "old") is None
    assert sync.late == 2
    assert sync.pending_stamps == ()


def test_a_repeated_input_for_a_pending_stamp_replaces_the_first() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(("a", "b"))
    sync.add("a", 1, "first")
    sync.add("a", 1, "second")
    matched = sync.add("b", 1, "b1")
    assert matched is not None and matched.items["a"] == "second"


def test_unknown_input_name_is_refused() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(("a",))
    with pytest.raises(KeyError, match="unknown input 'b'"):
        sync.add("b", 1, "x")


def test_set_inputs_changes_what_completes_a_stamp_and_discards_pending() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(("a", "b", "c"))
    sync.add("a", 1, "a1")
    sync.set_inputs(("a", "b"))
    assert sync.pending_stamps == ()
    assert sync.dropped == 0
    sync.add("a", 2, "a2")
    matched = sync.add("b", 2, "b2")
    assert matched is not None and set(matched.items) == {"a", "b"}


def test_single_input_matches_immediately() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(("a",))
    matched = sync.add("a", 3, "x")
    assert matched is not None and matched.stamp_ns == 3


@pytest.mark.parametrize(
    ("inputs", "max_pending", "message"),
    [
        ((), 10, "at least one input"),
        (("a", "a"), 10, "unique"),
        (("a",), 0, "max_pending"),
        (("a",), True, "max_pending"),
    ],
)
def test_invalid_construction_is_refused(inputs: tuple[str, ...], max_pending: int, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ExactTimeSynchronizer(inputs, max_pending=max_pending)


def test_clear_forgets_pending_and_last_match() -> None:
    sync: ExactTimeSynchronizer[str] = ExactTimeSynchronizer(("a", "b"))
    sync.add("a", 1, "a1")
    sync.add("b", 1, "b1")
    sync.add("a", 2, "a2")
    sync.clear()
    assert sync.pending_stamps == () and sync.last_matched_ns is None
    assert sync.add("a", 1, "again") is None  # not late any more
    assert sync.pending_stamps == (1,)


@given(st.lists(st.tuples(st.sampled_from(("a", "b")), st.integers(min_value=0, max_value=30)), max_size=80))
def test_matches_come_out_in_increasing_stamp_order_with_all_inputs(events: list[tuple[str, int]]) -> None:
    sync: ExactTimeSynchronizer[tuple[str, int]] = ExactTimeSynchronizer(("a", "b"), max_pending=4)
    stamps = []
    for name, stamp in events:
        matched = sync.add(name, stamp, (name, stamp))
        if matched is not None:
            assert set(matched.items) == {"a", "b"}
            assert all(item[1] == matched.stamp_ns for item in matched.items.values())
            stamps.append(matched.stamp_ns)
        assert len(sync.pending_stamps) <= 4
    assert stamps == sorted(set(stamps))
