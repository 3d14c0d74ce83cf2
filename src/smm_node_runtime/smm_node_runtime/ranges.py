"""Scalar ranges of config fields as dataclass field metadata, and their check (pure, no ROS)."""

from __future__ import annotations

import dataclasses
import typing

__all__ = ["RANGE_METADATA", "bounds", "check_bounds"]

RANGE_METADATA = "smm_range"
"""Dataclass field metadata key of a scalar field's closed range ``(low, high)``."""


def bounds(low: float, high: float) -> dict[str, tuple[float, float]]:
    """Field metadata: the scalar field's closed range [low, high] (ROS range and :func:`check_bounds`)."""
    if not low <= high:
        raise ValueError(f"empty range [{low}, {high}]")
    return {RANGE_METADATA: (low, high)}


def check_bounds(config: object) -> None:
    """Check every field of ``config`` with :func:`bounds` metadata: a number (int for int fields) in range.

    Raises:
        ValueError: naming the field, its range and the value.
    """
    hints = typing.get_type_hints(type(config))
    for item in dataclasses.fields(config):  # type: ignore[arg-type]
        value_range = item.metadata.get(RANGE_METADATA)
        if value_range is None:
            continue
        value = getattr(config, item.name)
        low, high = value_range
        integer = hints[item.name] is int
        number = isinstance(value, int) if integer else isinstance(value, (int, float))
        if isinstance(value, bool) or not number or not low <= value <= high:
            kind = "an integer" if integer else "a number"
            raise ValueError(f"{item.name} must be {kind} in [{low:g}, {high:g}], got {value!r}")
