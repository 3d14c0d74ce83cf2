"""Shapes of the dynamics' arguments: one sample (2,) on plain floats, or a batch (..., 2) on arrays."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
# A Python float (single-sample path) or a numpy array (batch path); only arithmetic is applied to it.
Real = Any


def joint_array(value: ArrayLike, name: str) -> FloatArray:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim == 0 or array.shape[-1] != 2:
        raise ValueError(f"{name} must have shape (2,) or (..., 2), got shape {array.shape}")
    return array


def is_batch(*arrays: FloatArray) -> bool:
    return any(array.ndim > 1 for array in arrays)


def components(array: FloatArray, batch: bool) -> tuple[Real, Real]:
    if batch:
        return array[..., 0], array[..., 1]
    first, second = array.tolist()
    return first, second


def trig_of(q: FloatArray, batch: bool) -> tuple[Real, Real, Real, Real]:
    alpha, beta = components(q, batch)
    if batch:
        return np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta)
    return math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)


def pack_vector(first: Real, second: Real, batch: bool) -> FloatArray:
    if batch:
        return np.stack(np.broadcast_arrays(first, second), axis=-1)
    return np.array((first, second), dtype=np.float64)


def pack_matrix(m11: Real, m12: Real, m21: Real, m22: Real, batch: bool) -> FloatArray:
    if batch:
        entries = np.broadcast_arrays(m11, m12, m21, m22)
        return np.stack(entries, axis=-1).reshape((*entries[0].shape, 2, 2))
    return np.array(((m11, m12), (m21, m22)), dtype=np.float64)
