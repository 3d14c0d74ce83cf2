"""Ranges of config fields as data, and the checks every config shares (ValueError naming field and value).

A numeric field declares its range once, in its dataclass field metadata (:func:`bounds`, :func:`above`,
:func:`at_least`, or :func:`no_range`); :func:`check_bounds` checks it in ``__post_init__``,
:mod:`smm_schema.fields` carries it to the parameters (docs/DESIGN.md, "Ranges of config fields").
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass
from typing import Any

__all__ = [
    "NO_RANGE",
    "RANGE_METADATA",
    "Range",
    "above",
    "at_least",
    "bounds",
    "check_bounds",
    "check_pair",
    "check_scalar",
    "field_range",
    "is_real",
    "no_range",
    "numeric_hint",
]


def is_real(value: Any) -> bool:
    """True for an int or float that is not a bool (NaN and infinities included)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _sign_range(positive: bool, non_negative: bool, allow_inf: bool) -> Range:
    """The range the flags of :func:`check_scalar` describe (``allow_inf``: +inf only)."""
    low = 0.0 if positive or non_negative else -math.inf
    return Range(low, math.inf, low_open=positive or low == -math.inf, high_open=not allow_inf)


def check_scalar(
    name: str,
    value: Any,
    *,
    positive: bool = False,
    non_negative: bool = False,
    allow_inf: bool = False,
) -> None:
    """Rejects non-numbers, NaN, infinities (unless ``allow_inf``) and out-of-range signs.

    Raises:
        ValueError: naming ``name`` and the value.
    """
    problem = _problem(value, _sign_range(positive, non_negative, allow_inf), integer=False)
    if problem is not None:
        raise ValueError(f"{name} must be {problem}, got {value!r}")


def check_pair(
    name: str,
    value: Any,
    *,
    positive: bool = False,
    non_negative: bool = False,
    allow_inf: bool = False,
) -> None:
    """Checks a per-joint ``tuple[float, float]`` (alpha, beta) field element-wise.

    Args:
        name: Field name for the message.
        value: The field's value.
        positive: Both elements must be > 0.
        non_negative: Both elements must be >= 0.
        allow_inf: +inf is allowed (e.g. "no limit").

    Raises:
        ValueError: not a 2-tuple of real numbers, NaN, an infinity not allowed, or out of range.
    """
    if not isinstance(value, tuple) or len(value) != 2:
        raise ValueError(f"{name} must be a tuple (alpha, beta) of 2 numbers, got {value!r}")
    value_range = _sign_range(positive, non_negative, allow_inf)
    for element in value:
        problem = _problem(element, value_range, integer=False)
        if problem is not None:
            raise ValueError(f"{name} must be {problem} for both joints, got {value!r}")


# ------------------------------------------------------------------------------- field ranges as data

RANGE_METADATA = "smm_range"
"""Dataclass field metadata key holding a numeric field's :class:`Range` (element range for tuples)."""


@dataclass(frozen=True)
class Range:
    """The values a number may take: from ``low`` to ``high``, each end open or closed.

    An infinite end that is open means "finite" (``(0, inf)``: any finite number > 0); closed, it admits
    the infinity itself (``(0, inf]``: inf stands for "no limit"). NaN is never in a range.

    Attributes:
        low: Lower end (may be -inf).
        high: Upper end (may be inf).
        low_open: ``low`` itself is excluded.
        high_open: ``high`` itself is excluded.
    """

    low: float
    high: float
    low_open: bool = False
    high_open: bool = False

    def __post_init__(self) -> None:
        if math.isnan(self.low) or math.isnan(self.high) or not self.low <= self.high:
            raise ValueError(f"empty range {self}")
        if self.low == self.high and (self.low_open or self.high_open):
            raise ValueError(f"empty range {self}")

    @property
    def unbounded(self) -> bool:
        """True for the whole real line of finite numbers (the explicit "no range")."""
        return self == NO_RANGE

    def contains(self, value: float) -> bool:
        """True when ``value`` (a real number) lies in the range."""
        if math.isnan(value):
            return False
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def requirement(self) -> str:
        """The range as a requirement: "> 0", ">= 1", "<= 5", "in [0.001, 3600]", "finite"."""
        if self.unbounded:
            return "finite"
        if self.high == math.inf:
            also = "" if self.high_open else " or inf"
            return f"{'>' if self.low_open else '>='} {_number(self.low)}{also}"
        if self.low == -math.inf:
            also = "" if self.low_open else " or -inf"
            return f"{'<' if self.high_open else '<='} {_number(self.high)}{also}"
        return f"in {self}"

    def __str__(self) -> str:
        """Interval notation, e.g. ``(0, inf)``, ``[0.001, 3600]``."""
        low, high = _number(self.low), _number(self.high)
        return f"{'(' if self.low_open else '['}{low}, {high}{')' if self.high_open else ']'}"


def _number(value: float) -> str:
    """A range end as written: integers exactly (``4294967295``), other numbers short (``0.001``)."""
    if math.isfinite(value) and value == int(value) and abs(value) < 2**53:
        return str(int(value))
    return f"{value:g}"


NO_RANGE = Range(-math.inf, math.inf, low_open=True, high_open=True)
"""Any finite number: the field has no range beyond finiteness."""


def bounds(low: float, high: float, *, low_open: bool = False, high_open: bool = False) -> dict[str, Range]:
    """Field metadata: the numeric field (or each element of a tuple field) lies in ``low .. high``."""
    return {RANGE_METADATA: Range(low, high, low_open, high_open)}


def above(low: float, *, inf: bool = False) -> dict[str, Range]:
    """Field metadata: a finite number > ``low`` (``inf=True``: +inf admitted too, meaning "no limit")."""
    return bounds(low, math.inf, low_open=True, high_open=not inf)


def at_least(low: float, *, inf: bool = False) -> dict[str, Range]:
    """Field metadata: a finite number >= ``low`` (``inf=True``: +inf admitted too, meaning "no limit")."""
    return bounds(low, math.inf, high_open=not inf)


def no_range() -> dict[str, Range]:
    """Field metadata: any finite number (the field states on purpose that it has no range)."""
    return {RANGE_METADATA: NO_RANGE}


def field_range(item: dataclasses.Field[Any]) -> Range | None:
    """The :class:`Range` a dataclass field declares in its metadata, or None."""
    value_range = item.metadata.get(RANGE_METADATA)
    return value_range if isinstance(value_range, Range) else None


def numeric_hint(hint: Any) -> Any:
    """``X`` for an optional ``X | None`` field's hint, else the hint itself."""
    arguments = typing.get_args(hint)
    if typing.get_origin(hint) in (typing.Union, types.UnionType) and type(None) in arguments:
        rest = [argument for argument in arguments if argument is not type(None)]
        return rest[0] if len(rest) == 1 else hint
    return hint


def _problem(value: Any, value_range: Range, integer: bool) -> str | None:
    """What ``value`` must be and is not, or None if it is a number (an int if ``integer``) in range."""
    finite = not (value_range.contains(math.inf) or value_range.contains(-math.inf))
    if not is_real(value) or (integer and not isinstance(value, int)) or math.isnan(value):
        return "an integer" if integer else "a finite number" if finite else "a real number"
    if value_range.contains(value):
        return None
    if math.isinf(value) and value_range.contains(math.copysign(1e300, value)):
        return "a finite number" if finite else f"a number other than {value}"
    return value_range.requirement()


def check_bounds(config: object) -> None:
    """Check every field of the dataclass ``config`` that declares a :class:`Range` (see :func:`bounds`).

    A scalar field must be a real number (an int, not bool, for ``int`` fields) in its range; a tuple field
    a tuple whose every element is (length and element type as its type hint says); an optional field
    (``X | None``) may also be None.

    Raises:
        ValueError: naming the field, what it must be, and the value.
    """
    hints = typing.get_type_hints(type(config))
    for item in dataclasses.fields(config):  # type: ignore[arg-type]
        value_range = field_range(item)
        if value_range is None:
            continue
        value = getattr(config, item.name)
        hint = numeric_hint(hints[item.name])
        if value is None and hint is not hints[item.name]:
            continue  # an optional field left out ("none")
        if typing.get_origin(hint) is not tuple:
            problem = _problem(value, value_range, hint is int)
            if problem is not None:
                raise ValueError(f"{item.name} must be {problem}, got {value!r}")
            continue
        arguments = typing.get_args(hint)
        variable = len(arguments) == 2 and arguments[1] is Ellipsis
        integer = arguments[0] is int
        if not isinstance(value, tuple) or (not variable and len(value) != len(arguments)):
            count = "numbers" if variable else f"{len(arguments)} numbers"
            what = " (alpha, beta)" if len(arguments) == 2 and not variable else ""
            raise ValueError(f"{item.name} must be a tuple{what} of {count}, got {value!r}")
        every = "both joints" if len(arguments) == 2 and not variable else "every element"
        for element in value:
            problem = _problem(element, value_range, integer)
            if problem is not None:
                raise ValueError(f"{item.name} must be {problem} for {every}, got {value!r}")
