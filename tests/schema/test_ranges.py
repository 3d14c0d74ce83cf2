"""smm_schema.ranges: the field checks every package's config dataclasses use."""

from __future__ import annotations

import math
from typing import Any

import pytest
from smm_schema.ranges import check_pair, check_scalar, is_real


@pytest.mark.parametrize(
    ("value", "flags", "message"),
    [
        ((1.0,), {}, "must be a tuple (alpha, beta) of 2 numbers"),
        ([1.0, 2.0], {}, "must be a tuple (alpha, beta) of 2 numbers"),
        ((1.0, "2"), {}, "must be a finite number for both joints"),
        ((True, 1.0), {}, "must be a finite number for both joints"),
        ((math.nan, 1.0), {}, "must be a finite number for both joints"),
        ((math.nan, 1.0), {"allow_inf": True}, "must be a real number for both joints"),
        ((1.0, math.inf), {}, "must be a finite number for both joints"),
        ((-math.inf, 1.0), {"allow_inf": True}, "must be a number other than -inf for both joints"),
        ((0.0, 1.0), {"positive": True}, "must be > 0 for both joints"),
        ((1.0, -0.5), {"non_negative": True}, "must be >= 0 for both joints"),
    ],
)
def test_check_pair_rejects_with_the_field_name(value: Any, flags: dict[str, bool], message: str) -> None:
    with pytest.raises(ValueError, match=r"^gain ") as raised:
        check_pair("gain", value, **flags)
    assert message in str(raised.value)


@pytest.mark.parametrize(
    ("value", "flags"),
    [
        ((0.0, -1.0), {}),
        ((0, 2), {"non_negative": False}),
        ((1.0, math.inf), {"allow_inf": True, "positive": True}),
    ],
)
def test_check_pair_accepts_valid_pairs(value: Any, flags: dict[str, bool]) -> None:
    check_pair("gain", value, **flags)


@pytest.mark.parametrize(
    ("value", "flags", "message"),
    [
        ("1", {}, "must be a finite number"),
        (math.nan, {}, "must be a finite number"),
        (math.nan, {"allow_inf": True}, "must be a real number"),
        (math.inf, {}, "must be a finite number"),
        (0.0, {"positive": True}, "must be > 0"),
        (-1e-12, {"non_negative": True}, "must be >= 0"),
    ],
)
def test_check_scalar_rejects_with_the_field_name(value: Any, flags: dict[str, bool], message: str) -> None:
    with pytest.raises(ValueError, match=r"^period ") as raised:
        check_scalar("period", value, **flags)
    assert message in str(raised.value)


def test_check_scalar_accepts_inf_only_when_allowed_and_positive() -> None:
    check_scalar("limit", math.inf, allow_inf=True)
    with pytest.raises(ValueError, match="must be a number other than -inf"):
        check_scalar("limit", -math.inf, allow_inf=True)


@pytest.mark.parametrize(
    ("value", "expected"), [(1, True), (1.5, True), (math.nan, True), (True, False), ("1", False)]
)
def test_is_real(value: Any, expected: bool) -> None:
    assert is_real(value) is expected
