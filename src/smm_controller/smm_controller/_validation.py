"""Validation helpers shared by the config dataclasses (plain ValueError naming field and value)."""

from __future__ import annotations

import math
import types
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt
from smm_schema.ranges import check_pair, check_scalar, is_real

__all__ = [
    "FloatArray",
    "as_joint_vector",
    "as_reference",
    "check_dt",
    "check_instance",
    "check_pair",
    "check_scalar",
    "internals_view",
    "is_real",
    "readonly_copies",
]

FloatArray = npt.NDArray[np.float64]

InstanceT = TypeVar("InstanceT")


def check_instance(name: str, value: object, expected: type[InstanceT]) -> InstanceT:
    """Returns ``value`` if it is an ``expected``; else a TypeError naming the argument and both types.

    Used by ``reconfigure``: a config of another algorithm would otherwise fail later, mid-step.
    """
    if not isinstance(value, expected):
        raise TypeError(f"{name} must be a {expected.__name__}, got {type(value).__name__}: {value!r}")
    return value


def check_dt(dt: float) -> None:
    """A step size must be a finite positive number of seconds."""
    if not is_real(dt) or not math.isfinite(dt) or dt <= 0.0:
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
