"""Checks of config fields shared by every package (a plain ValueError naming the field and the value).

The per-joint convention of the stack is a ``tuple[float, float]`` (alpha, beta); smm_dynamics is the one
package every algorithm and the simulator depend on, so the checks live here once.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["check_pair", "check_scalar", "is_real"]


def is_real(value: Any) -> bool:
    """True for an int or float that is not a bool (NaN and infinities included)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _out_of_range(value: Any, *, positive: bool, non_negative: bool, allow_inf: bool) -> str | None:
    """What ``value`` must be and is not ("a real number", "finite", "> 0", ">= 0"), or None if it is fine."""
    if not is_real(value) or math.isnan(value):
        return "a real number"
    if math.isinf(value) and not (allow_inf and value > 0.0):
        return "finite"
    if positive and not value > 0.0:
        return "> 0"
    if non_negative and not value >= 0.0:
        return ">= 0"
    return None


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
    problem = _out_of_range(value, positive=positive, non_negative=non_negative, allow_inf=allow_inf)
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
    for element in value:
        problem = _out_of_range(element, positive=positive, non_negative=non_negative, allow_inf=allow_inf)
        if problem is not None:
            raise ValueError(f"{name} must be {problem} for both joints, got {value!r}")
