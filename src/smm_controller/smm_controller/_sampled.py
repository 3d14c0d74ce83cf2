"""The interface every reference generator shares: ``rows(t)``, ``evaluate(t)``, ``sample(times)``."""

from __future__ import annotations

from typing import Protocol

import numpy as np
import numpy.typing as npt

from smm_controller._validation import FloatArray, check_scalar

__all__ = ["Reference", "Rows"]


Rows = tuple[tuple[float, float], tuple[float, float], tuple[float, float]]
"""A reference at one time as floats: (position, velocity, acceleration), each (alpha, beta)."""


class Reference(Protocol):
    """A reference generator: ``rows(t)`` (floats), ``evaluate(t)`` (3, 2), ``sample(times)`` (n, 3, 2)."""

    def rows(self, t: float) -> Rows:
        """Position (rad), velocity (rad/s), acceleration (rad/s^2) at time t (s), as float pairs."""
        ...

    def evaluate(self, t: float) -> FloatArray:
        """Position, velocity and acceleration at time t (s), shape (3, 2)."""
        ...

    def sample(self, times: npt.ArrayLike) -> FloatArray:
        """The same at every time of ``times`` (s), shape (n, 3, 2)."""
        ...


class _Sampled:
    """evaluate(t) and sample(times) in terms of each generator's scalar rows(t).

    One formula per generator, in plain floats: the offline loop (``sample`` over a run) and the nodes
    (``rows`` or ``evaluate`` at each stamp) compute the same values bit for bit, and a node's step costs
    no array set-up.
    """

    def rows(self, t: float) -> Rows:
        """Position (rad), velocity (rad/s), acceleration (rad/s^2) at time t (s), as float pairs."""
        raise NotImplementedError

    def evaluate(self, t: float) -> FloatArray:
        """Position, velocity and acceleration at time t (s), shape (3, 2)."""
        check_scalar("t", t)
        return np.array(self.rows(float(t)))

    def sample(self, times: npt.ArrayLike) -> FloatArray:
        """References at every time of ``times`` (s), shape (n, 3, 2)."""
        array = np.asarray(times, dtype=np.float64)
        if array.ndim != 1 or not np.all(np.isfinite(array)):
            raise ValueError(f"times must be a finite 1-D array (s), got shape {array.shape}")
        sampled: FloatArray = np.array([self.rows(t) for t in array.tolist()], dtype=np.float64).reshape(
            array.size, 3, 2
        )
        return sampled

    def __call__(self, t: float) -> FloatArray:
        """Same as :meth:`evaluate`."""
        return self.evaluate(t)
