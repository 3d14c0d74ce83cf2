"""Reference trajectories q_d(t) with analytic derivatives (SPEC section 3).

Every generator returns, for a time t (s), an array of shape (3, 2): rows position (rad), velocity
(rad/s), acceleration (rad/s^2); columns alpha, beta. Generators are pure functions of t.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from smm_controller._validation import FloatArray, check_pair, check_scalar

__all__ = [
    "REFERENCE_KINDS",
    "RampHoldReference",
    "Reference",
    "SineReference",
    "StepReference",
    "make_reference",
]


class Reference(Protocol):
    """A reference generator: ``evaluate(t)`` -> shape (3, 2), ``sample(times)`` -> (n, 3, 2)."""

    def evaluate(self, t: float) -> FloatArray:
        """Position, velocity and acceleration at time t (s), shape (3, 2)."""
        ...

    def sample(self, times: npt.ArrayLike) -> FloatArray:
        """The same at every time of ``times`` (s), shape (n, 3, 2)."""
        ...


def _as_times(times: npt.ArrayLike) -> FloatArray:
    array = np.asarray(times, dtype=np.float64)
    if array.ndim != 1 or not np.all(np.isfinite(array)):
        raise ValueError(f"times must be a finite 1-D array (s), got shape {array.shape}")
    return array


def _stack(position: FloatArray, velocity: FloatArray, acceleration: FloatArray) -> FloatArray:
    """Per-joint arrays of shape (n, 2) -> references of shape (n, 3, 2)."""
    stacked: FloatArray = np.stack((position, velocity, acceleration), axis=1)
    return stacked


class _Sampled:
    """evaluate(t) in terms of the vectorised sample(times) of each generator."""

    def sample(self, times: npt.ArrayLike) -> FloatArray:
        """References at every time of ``times`` (s), shape (n, 3, 2)."""
        raise NotImplementedError

    def evaluate(self, t: float) -> FloatArray:
        """Position, velocity and acceleration at time t (s), shape (3, 2)."""
        check_scalar("t", t)
        single: FloatArray = self.sample(np.array((t,)))[0]
        return single

    def __call__(self, t: float) -> FloatArray:
        """Same as :meth:`evaluate`."""
        return self.evaluate(t)


@dataclass(frozen=True)
class StepReference(_Sampled):
    """q_d = amplitude for t >= start_time, else 0; velocity and acceleration 0.

    The derivatives are zero, not impulses: a step has no finite derivative at start_time.

    Attributes:
        amplitude: Step height per joint (rad), finite.
        start_time: Time of the step (s), finite, >= 0.
    """

    amplitude: tuple[float, float] = (1.0, 0.785)
    start_time: float = 0.0

    def __post_init__(self) -> None:
        check_pair("amplitude", self.amplitude)
        check_scalar("start_time", self.start_time, non_negative=True)

    def sample(self, times: npt.ArrayLike) -> FloatArray:
        """References at every time of ``times`` (s), shape (n, 3, 2)."""
        t = _as_times(times)
        on = (t >= self.start_time).astype(np.float64)[:, None]
        zeros = np.zeros((t.size, 2))
        return _stack(on * np.asarray(self.amplitude), zeros, zeros)


@dataclass(frozen=True)
class SineReference(_Sampled):
    """q_d = amplitude sin(omega t + phase) (eq. 41 with the defaults).

    Attributes:
        amplitude: Per joint (rad), finite.
        angular_frequency: omega (rad/s), finite, > 0.
        phase: Per joint (rad), finite.
    """

    amplitude: tuple[float, float] = (1.0, 0.785)
    angular_frequency: float = math.pi
    phase: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        check_pair("amplitude", self.amplitude)
        check_scalar("angular_frequency", self.angular_frequency, positive=True)
        check_pair("phase", self.phase)

    def sample(self, times: npt.ArrayLike) -> FloatArray:
        """References at every time of ``times`` (s), shape (n, 3, 2)."""
        omega = self.angular_frequency
        angle = omega * _as_times(times)[:, None] + np.asarray(self.phase)
        amplitude = np.asarray(self.amplitude)
        sine = amplitude * np.sin(angle)
        return _stack(sine, amplitude * omega * np.cos(angle), -(omega * omega) * sine)


@dataclass(frozen=True)
class RampHoldReference(_Sampled):
    """Moves from ``initial`` to ``target`` during [start_time, start_time + ramp_time], then holds.

    ``profile="linear"``: constant velocity during the ramp (acceleration 0; its impulses at the
    corners are not represented). ``profile="quintic"``: minimum-jerk polynomial
    s(x) = 10 x^3 - 15 x^4 + 6 x^5, x = (t - start_time)/ramp_time, so velocity and acceleration are
    continuous and zero at both ends.

    Attributes:
        target: Final position per joint (rad), finite.
        ramp_time: Duration of the ramp (s), > 0.
        start_time: Start of the ramp (s), >= 0.
        initial: Position before the ramp per joint (rad), finite.
        profile: "linear" or "quintic".
    """

    target: tuple[float, float] = (1.0, 0.785)
    ramp_time: float = 1.0
    start_time: float = 0.0
    initial: tuple[float, float] = (0.0, 0.0)
    profile: str = "quintic"

    def __post_init__(self) -> None:
        check_pair("target", self.target)
        check_scalar("ramp_time", self.ramp_time, positive=True)
        check_scalar("start_time", self.start_time, non_negative=True)
        check_pair("initial", self.initial)
        if self.profile not in ("linear", "quintic"):
            raise ValueError(f"profile must be 'linear' or 'quintic', got {self.profile!r}")

    def sample(self, times: npt.ArrayLike) -> FloatArray:
        """References at every time of ``times`` (s), shape (n, 3, 2)."""
        x = np.clip((_as_times(times) - self.start_time) / self.ramp_time, 0.0, 1.0)[:, None]
        if self.profile == "linear":
            shape = x
            rate = ((x > 0.0) & (x < 1.0)).astype(np.float64)
            curvature = np.zeros_like(x)
        else:
            shape = x**3 * (10.0 - 15.0 * x + 6.0 * x * x)
            rate = 30.0 * x * x * (1.0 - x) ** 2
            curvature = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)
        initial = np.asarray(self.initial)
        span = np.asarray(self.target) - initial
        return _stack(
            initial + span * shape, span * rate / self.ramp_time, span * curvature / self.ramp_time**2
        )


#: Names accepted by :func:`make_reference`.
REFERENCE_KINDS: dict[str, type[StepReference] | type[SineReference] | type[RampHoldReference]] = {
    "step": StepReference,
    "sine": SineReference,
    "ramp_hold": RampHoldReference,
}


def _as_pair(value: Any) -> Any:
    # ROS parameters and YAML give lists; configs store tuples.
    return tuple(value) if isinstance(value, (list, np.ndarray)) else value


def make_reference(kind: str, **params: Any) -> StepReference | SineReference | RampHoldReference:
    """Builds a reference generator by name.

    Args:
        kind: "step", "sine" or "ramp_hold".
        **params: Fields of the generator's dataclass (lists are accepted for per-joint fields).

    Returns:
        The generator.
    """
    try:
        factory = REFERENCE_KINDS[kind]
    except KeyError:
        raise ValueError(f"kind must be one of {sorted(REFERENCE_KINDS)}, got {kind!r}") from None
    try:
        return factory(**{key: _as_pair(value) for key, value in params.items()})
    except TypeError as error:
        raise ValueError(f"invalid parameters for reference kind {kind!r}: {error}") from None
