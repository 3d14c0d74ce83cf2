"""Reference trajectories q_d(t) with analytic derivatives (SPEC section 3).

Every generator returns, for a time t (s), an array of shape (3, 2): rows position (rad), velocity
(rad/s), acceleration (rad/s^2); columns alpha, beta. Generators are pure functions of t.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from smm_schema.ranges import above, at_least, check_bounds, no_range

from smm_controller._sampled import Reference, Rows, _Sampled
from smm_controller.excitation import ExcitationReference

__all__ = [
    "REFERENCE_KINDS",
    "ExcitationReference",
    "RampHoldReference",
    "Reference",
    "ReferenceClock",
    "ReferenceGenerator",
    "Rows",
    "SineReference",
    "StepReference",
    "make_reference",
]


@dataclass(frozen=True)
class StepReference(_Sampled):
    """q_d = amplitude for t >= start_time, else 0; velocity and acceleration 0.

    The derivatives are zero, not impulses: a step has no finite derivative at start_time.

    Attributes:
        amplitude: Step height per joint (rad), finite.
        start_time: Time of the step (s), finite, >= 0.
    """

    amplitude: tuple[float, float] = field(default=(1.0, 0.785), metadata=no_range())
    start_time: float = field(default=0.0, metadata=at_least(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)

    def rows(self, t: float) -> Rows:
        """Position (rad), velocity (rad/s), acceleration (rad/s^2) at time t (s), as float pairs."""
        alpha, beta = self.amplitude if t >= self.start_time else (0.0, 0.0)
        return ((float(alpha), float(beta)), (0.0, 0.0), (0.0, 0.0))


@dataclass(frozen=True)
class SineReference(_Sampled):
    """q_d = amplitude sin(omega t + phase) (eq. 41 with the defaults).

    Attributes:
        amplitude: Per joint (rad), finite.
        angular_frequency: omega (rad/s), finite, > 0.
        phase: Per joint (rad), finite.
    """

    amplitude: tuple[float, float] = field(default=(1.0, 0.785), metadata=no_range())
    angular_frequency: float = field(default=math.pi, metadata=above(0.0))
    phase: tuple[float, float] = field(default=(0.0, 0.0), metadata=no_range())

    def __post_init__(self) -> None:
        check_bounds(self)

    def rows(self, t: float) -> Rows:
        """Position (rad), velocity (rad/s), acceleration (rad/s^2) at time t (s), as float pairs."""
        omega = self.angular_frequency
        (amplitude_a, amplitude_b), (phase_a, phase_b) = self.amplitude, self.phase
        angle_a, angle_b = omega * t + phase_a, omega * t + phase_b
        sine_a, sine_b = amplitude_a * math.sin(angle_a), amplitude_b * math.sin(angle_b)
        return (
            (sine_a, sine_b),
            (amplitude_a * omega * math.cos(angle_a), amplitude_b * omega * math.cos(angle_b)),
            (-(omega * omega) * sine_a, -(omega * omega) * sine_b),
        )


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

    target: tuple[float, float] = field(default=(1.0, 0.785), metadata=no_range())
    ramp_time: float = field(default=1.0, metadata=above(0.0))
    start_time: float = field(default=0.0, metadata=at_least(0.0))
    initial: tuple[float, float] = field(default=(0.0, 0.0), metadata=no_range())
    profile: str = "quintic"

    def __post_init__(self) -> None:
        check_bounds(self)
        if self.profile not in ("linear", "quintic"):
            raise ValueError(f"profile must be 'linear' or 'quintic', got {self.profile!r}")

    def rows(self, t: float) -> Rows:
        """Position (rad), velocity (rad/s), acceleration (rad/s^2) at time t (s), as float pairs."""
        x = min(max((t - self.start_time) / self.ramp_time, 0.0), 1.0)
        if self.profile == "linear":
            shape, rate, curvature = x, (1.0 if 0.0 < x < 1.0 else 0.0), 0.0
        else:
            shape = x**3 * (10.0 - 15.0 * x + 6.0 * x * x)
            rate = 30.0 * x * x * (1.0 - x) ** 2
            curvature = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)
        (initial_a, initial_b), (target_a, target_b) = self.initial, self.target
        span_a, span_b = target_a - initial_a, target_b - initial_b
        ramp = self.ramp_time
        return (
            (initial_a + span_a * shape, initial_b + span_b * shape),
            (span_a * rate / ramp, span_b * rate / ramp),
            (span_a * curvature / ramp**2, span_b * curvature / ramp**2),
        )


ReferenceGenerator = StepReference | SineReference | RampHoldReference | ExcitationReference
"""Any of the reference generators (each a frozen config dataclass with ``rows``/``evaluate``/``sample``)."""

#: Names accepted by :func:`make_reference`.
REFERENCE_KINDS: dict[
    str, type[StepReference] | type[SineReference] | type[RampHoldReference] | type[ExcitationReference]
] = {
    "step": StepReference,
    "sine": SineReference,
    "ramp_hold": RampHoldReference,
    "excite": ExcitationReference,
}


def _as_pair(value: Any) -> Any:
    # ROS parameters and YAML give lists; configs store tuples.
    return tuple(value) if isinstance(value, (list, np.ndarray)) else value


def make_reference(kind: str, **params: Any) -> ReferenceGenerator:
    """Builds a reference generator by name.

    Args:
        kind: "step", "sine", "ramp_hold" or "excite".
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


_NS_PER_S = 1_000_000_000


class ReferenceClock:
    """Time of the reference from measurement stamps: t = (stamp - first stamp) / 1e9 (s).

    t = 0 at the first stamp it is asked about, as a trajectory controller starts its trajectory at the
    first state it sees. Exact integer difference, then one rounding: the offline loop's ``t_ns / 1e9``
    for the same stamps.

    Args:
        announce: Called once with a one-line note when t = 0 is set (a node passes its logger's ``info``),
            so a run's logs say which measurement stamp its reference time starts at.
    """

    def __init__(self, announce: Callable[[str], object] | None = None) -> None:
        self._first_stamp_ns: int | None = None
        self._announce = announce

    @property
    def first_stamp_ns(self) -> int | None:
        """Stamp (ns) that is t = 0; None before the first call of :meth:`time_s`."""
        return self._first_stamp_ns

    def time_s(self, stamp_ns: int) -> float:
        """Reference time (s) at ``stamp_ns`` (ns); the first stamp ever passed becomes t = 0."""
        if self._first_stamp_ns is None:
            self._first_stamp_ns = stamp_ns
            if self._announce is not None:
                self._announce(f"reference t = 0 s at measurement stamp {stamp_ns} ns")
        return (stamp_ns - self._first_stamp_ns) / _NS_PER_S
