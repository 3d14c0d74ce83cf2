"""Every config of the stack does what its range metadata says: a value just outside a finite end is refused,
the closed ends themselves are accepted (the check is ``check_bounds``, not a second one by hand)."""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any

import pytest
from smm_schema.ranges import Range, field_range, numeric_hint
from test_layering import CONFIGS, numeric_fields


def _outside(value_range: Range, integer: bool) -> list[float]:
    """Values just outside each finite end of ``value_range``."""
    values: list[float] = []
    if math.isfinite(value_range.low):
        values.append(
            value_range.low
            if value_range.low_open
            else value_range.low - 1
            if integer
            else math.nextafter(value_range.low, -math.inf)
        )
    if math.isfinite(value_range.high):
        values.append(
            value_range.high
            if value_range.high_open
            else value_range.high + 1
            if integer
            else math.nextafter(value_range.high, math.inf)
        )
    return [int(v) if integer else v for v in values]


def _with(config: Any, name: str, hint: Any, value: float) -> Any:
    """``config`` with field ``name`` set to ``value`` (every element of a tuple field)."""
    if typing.get_origin(hint) is tuple:
        arguments = typing.get_args(hint)
        length = len(getattr(config, name) or (0, 0)) if Ellipsis in arguments else len(arguments)
        return dataclasses.replace(config, **{name: (value,) * max(length, 1)})
    return dataclasses.replace(config, **{name: value})


def _cases() -> list[Any]:
    cases = []
    for cls in CONFIGS:
        hints = typing.get_type_hints(cls)
        for item in numeric_fields(cls):
            value_range = field_range(item)
            if value_range is None or not item.init:
                continue
            hint = numeric_hint(hints[item.name])
            element = typing.get_args(hint)[0] if typing.get_origin(hint) is tuple else hint
            for value in _outside(value_range, element is int):
                cases.append(
                    pytest.param(cls, item.name, hint, value, id=f"{cls.__name__}.{item.name}={value}")
                )
    return cases


CASES = _cases()


def test_there_are_cases_for_the_bridge_and_the_plant() -> None:
    ids = {(case.values[0].__name__, case.values[1]) for case in CASES}
    assert {
        ("AdmissionConfig", "period_ns"),
        ("LinkConfig", "baudrate"),
        ("PlantConfig", "control_period"),
    } <= ids


@pytest.mark.parametrize(("cls", "name", "hint", "value"), CASES)
def test_a_value_just_outside_the_declared_range_is_refused_naming_the_field(
    cls: type, name: str, hint: Any, value: float
) -> None:
    default = cls()
    with pytest.raises(ValueError, match=name):
        _with(default, name, hint, value)


@pytest.mark.parametrize(
    ("cls_name", "name", "value"),
    [("AdmissionConfig", "period_ns", 2_000_000_000), ("LinkConfig", "baudrate", 200_000_000)],
)
def test_the_two_that_once_disagreed_refuse_what_ros_refuses(cls_name: str, name: str, value: int) -> None:
    (cls,) = [cls for cls in CONFIGS if cls.__name__ == cls_name]
    (item,) = [item for item in dataclasses.fields(cls) if item.name == name]
    value_range = field_range(item)
    assert value_range is not None and not value_range.contains(value)
    with pytest.raises(ValueError, match=f"{name} must be"):
        dataclasses.replace(cls(), **{name: value})
    accepted = dataclasses.replace(cls(), **{name: int(value_range.high)})
    assert getattr(accepted, name) == int(value_range.high)
