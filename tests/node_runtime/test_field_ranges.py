"""Ranges as data: every numeric config field declares one (smm_schema.ranges), checked by the config,
carried by the schema and turned into the ROS descriptor; a field without one is found."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from rcl_interfaces.msg import ParameterType
from smm_node_runtime.parameters import parameter_descriptor
from smm_schema.fields import config_fields, unranged_fields
from smm_schema.ranges import NO_RANGE, Range, above, at_least, bounds, check_bounds, no_range


@dataclass(frozen=True)
class Ranged:
    """A config whose every numeric field declares its range.

    Attributes:
        gain: Per joint (1/s), > 0.
        limit: Per joint (N m), > 0; inf = none.
        period: Step (s), in (0, 1].
        count: How many, >= 3.
        odd: Strictly between 0 and 10.
        offset: Any finite number (rad).
        label: Not a number.
    """

    gain: tuple[float, float] = field(default=(1.0, 2.0), metadata=above(0.0))
    limit: tuple[float, float] = field(default=(math.inf, 5.0), metadata=above(0.0, inf=True))
    period: float = field(default=0.5, metadata=bounds(0.0, 1.0, low_open=True))
    count: int = field(default=3, metadata=at_least(3))
    odd: int = field(default=5, metadata=bounds(0, 10, low_open=True, high_open=True))
    offset: float = field(default=0.0, metadata=no_range())
    label: str = "x"

    def __post_init__(self) -> None:
        check_bounds(self)


@dataclass(frozen=True)
class Planted:
    """A config with one numeric field that forgot its range.

    Attributes:
        inner: A ranged block (nested fields are walked).
        forgotten: A scalar (m) whose docstring says > 0, which defines nothing.
    """

    inner: Ranged = Ranged()
    forgotten: float = 1.0


def test_a_numeric_field_without_a_range_is_found_even_when_its_docstring_states_one() -> None:
    assert unranged_fields(Ranged) == ()
    assert unranged_fields(Planted) == ("forgotten",)
    (forgotten,) = (item for item in config_fields(Planted) if item.name == "forgotten")
    assert "> 0" in forgotten.description
    assert forgotten.value_range is None


def test_the_schema_carries_each_fields_range_and_none_for_non_numbers() -> None:
    ranges = {item.name: item.value_range for item in config_fields(Ranged)}
    assert ranges["gain"] == Range(0.0, math.inf, low_open=True, high_open=True)
    assert ranges["limit"] == Range(0.0, math.inf, low_open=True)
    assert ranges["offset"] is NO_RANGE
    assert ranges["label"] is None


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"gain": (0.0, 1.0)}, "gain must be > 0 for both joints, got (0.0, 1.0)"),
        ({"gain": (1.0, math.inf)}, "gain must be a finite number for both joints, got (1.0, inf)"),
        ({"gain": (1.0,)}, "gain must be a tuple (alpha, beta) of 2 numbers, got (1.0,)"),
        ({"limit": (-1.0, 1.0)}, "limit must be > 0 or inf for both joints, got (-1.0, 1.0)"),
        ({"period": 0.0}, "period must be in (0, 1], got 0.0"),
        ({"period": 1.5}, "period must be in (0, 1], got 1.5"),
        ({"period": math.nan}, "period must be a finite number, got nan"),
        ({"count": 2}, "count must be >= 3, got 2"),
        ({"count": 3.0}, "count must be an integer, got 3.0"),
        ({"count": True}, "count must be an integer, got True"),
        ({"odd": 10}, "odd must be in (0, 10), got 10"),
        ({"offset": -math.inf}, "offset must be a finite number, got -inf"),
    ],
)
def test_check_bounds_refuses_naming_the_field_its_range_and_the_value(
    changes: dict[str, object], message: str
) -> None:
    with pytest.raises(ValueError) as raised:
        Ranged(**changes)  # type: ignore[arg-type]
    assert str(raised.value) == message


def test_inf_is_admitted_only_where_the_range_closes_at_it() -> None:
    assert Ranged(limit=(math.inf, math.inf)).limit == (math.inf, math.inf)


@given(st.floats(allow_nan=False), st.booleans(), st.booleans())
def test_a_value_passes_check_bounds_exactly_when_the_range_contains_it(
    value: float, low_open: bool, high_open: bool
) -> None:
    value_range = Range(-1.0, 1.0, low_open, high_open)
    expected = (value > -1.0 if low_open else value >= -1.0) and (value < 1.0 if high_open else value <= 1.0)
    assert value_range.contains(value) is expected


def test_an_empty_range_is_refused() -> None:
    with pytest.raises(ValueError, match="empty range"):
        bounds(1.0, 0.0)
    with pytest.raises(ValueError, match="empty range"):
        bounds(1.0, 1.0, low_open=True)


def _descriptors() -> dict[str, Any]:
    return {item.name: parameter_descriptor(item, item.name) for item in config_fields(Ranged)}


def test_a_scalar_double_gets_the_closed_ros_range_and_its_open_end_in_words() -> None:
    period = _descriptors()["period"]
    assert period.type == ParameterType.PARAMETER_DOUBLE
    (ros_range,) = period.floating_point_range
    assert (ros_range.from_value, ros_range.to_value) == (0.0, 1.0)
    assert period.additional_constraints == "in (0, 1]"


def test_an_integer_range_is_exact_open_ends_moved_inward() -> None:
    descriptors = _descriptors()
    (count,) = descriptors["count"].integer_range
    assert (count.from_value, count.to_value) == (3, 2**63 - 1)
    (odd,) = descriptors["odd"].integer_range
    assert (odd.from_value, odd.to_value) == (1, 9)


def test_arrays_state_their_element_range_in_words_and_no_range_declares_none() -> None:
    descriptors = _descriptors()
    gain = descriptors["gain"]
    assert not gain.floating_point_range
    assert gain.additional_constraints == "2 values, per joint (alpha, beta), each > 0"
    limit = descriptors["limit"]
    assert limit.additional_constraints == "2 values, per joint (alpha, beta), each > 0 or inf"
    offset = descriptors["offset"]
    assert not offset.floating_point_range
    assert offset.additional_constraints == ""
