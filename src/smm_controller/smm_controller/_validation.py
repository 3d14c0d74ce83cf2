"""Validation helpers shared by the config dataclasses (plain ValueError naming field and value)."""

from __future__ import annotations

import math
import types
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

InstanceT = TypeVar("InstanceT")


def _is_real(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_scalar(
    name: str,
    value: Any,
    *,
    positive: bool = False,
    non_negative: bool = False,
    allow_inf: bool = False,
) -> None:
    """Rejects non-numbers, NaN, infinities (unless ``allow_inf``) and out-of-range signs."""
    if not _is_real(value) or math.isnan(value):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    if math.isinf(value) and not (allow_inf and value > 0.0):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if positive and not value > 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    if non_negative and not value >= 0.0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")


def check_pair(
    name: str,
    value: Any,
    *,
    positive: bool = False,
    non_negative: bool = False,
    allow_inf: bool = False,
) -> None:
    """Checks a per-joint ``tuple[float, float]`` (alpha, beta) field element-wise."""
    if not isinstance(value, tuple) or len(value) != 2:
        raise ValueError(f"{name} must be a tuple (alpha, beta) of 2 numbers, got {value!r}")
    for element in value:
        if not _is_real(element) or math.isnan(element):
            raise ValueError(f"{name} must contain real numbers, got {value!r}")
        if math.isinf(element) and not (allow_inf and element > 0.0):
            raise ValueError(f"{name} must be finite, got {value!r}")
        if positive and not element > 0.0:
            raise ValueError(f"{name} must be > 0 for both joints, got {value!r}")
        if non_negative and not element >= 0.0:
            raise ValueError(f"{name} must be >= 0 for both joints, got {value!r}")


def check_grid_points(value: Any) -> None:
    """The defuzzification grid needs at least 3 points (an integer)."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 3:
        raise ValueError(f"grid_points must be an integer >= 3, got {value!r}")


def check_instance(name: str, value: object, expected: type[InstanceT]) -> InstanceT:
    """Returns ``value`` if it is an ``expected``; else a TypeError naming the argument and both types.

    Used by ``reconfigure``: a config of another algorithm would otherwise fail later, mid-step.
    """
    if not isinstance(value, expected):
        raise TypeError(f"{name} must be a {expected.__name__}, got {type(value).__name__}: {value!r}")
    return value


def check_dt(dt: float) -> None:
    """A step size must be a finite positive number of seconds."""
    if not _is_real(dt) or not math.isfinite(dt) or dt <= 0.0:
        raise ValueError(f"dt must be a finite number of seconds > 0, got {dt!r}")


def as_joint_vector(name: str, value: npt.ArrayLike) -> tuple[float, float]:
    """Converts a per-joint input of shape (2,) to two floats, rejecting other shapes and NaN/Inf."""
    array = np.asarray(value, dtype=np.float64)
    if array.shape != (2,):
        raise ValueError(f"{name} must have shape (2,), got shape {array.shape}")
    first, second = array.tolist()
    if not (math.isfinite(first) and math.isfinite(second)):
        raise ValueError(f"{name} must be finite, got {array!r}")
    return first, second


def as_reference(value: npt.ArrayLike) -> FloatArray:
    """Checks a reference of shape (3, 2): rows position, velocity, acceleration; columns joints."""
    array = np.asarray(value, dtype=np.float64)
    if array.shape != (3, 2):
        raise ValueError(f"reference must have shape (3, 2), got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"reference must be finite, got {array!r}")
    return array


def readonly_copies(values: dict[str, Any]) -> dict[str, FloatArray]:
    """Converts values to read-only float arrays (copies), for ``internals`` views."""
    frozen = {}
    for key, value in values.items():
        array = np.array(value, dtype=np.float64)
        array.flags.writeable = False
        frozen[key] = array
    return frozen


def internals_view(keys: tuple[str, ...], flat: tuple[float, ...]) -> Mapping[str, FloatArray]:
    """Read-only mapping ``keys[i] -> array(flat[2 i], flat[2 i + 1])`` of read-only copies."""
    return types.MappingProxyType(
        readonly_copies({key: flat[2 * i : 2 * i + 2] for i, key in enumerate(keys)})
    )
