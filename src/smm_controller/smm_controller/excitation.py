"""Excitation reference for identification: a finite Fourier series per joint, at rest at both ends.

Scaled to the largest amplitude within its position, velocity, acceleration and nominal-torque limits.
The series and its design: docs/IDENTIFICATION.md, "The excitation".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from smm_schema.ranges import above, at_least, check_bounds, no_range

from smm_controller._sampled import Rows, _Sampled
from smm_controller._validation import FloatArray
from smm_dynamics import SMMParameters, inverse_dynamics

__all__ = ["ExcitationReference"]

# Grid points per period on which the limits are checked; the scale found on the grid is taken times
# _MARGIN, so that the limits also hold between grid points (there the excess is O((w_N T / grid)^2),
# below 1e-5 relative for the defaults).
_GRID = 4096
_MARGIN = 0.999
_BISECTIONS = 60


def _shape(harmonics: int, joint: int, period: float) -> tuple[FloatArray, FloatArray]:
    """Unscaled velocity coefficients (c, d) of one joint, each shape (harmonics,), at rest at tau = 0."""
    k = np.arange(1, harmonics + 1, dtype=np.float64)
    # Schroeder phases, mirrored for the second joint and shifted by a quarter turn.
    phase = (
        -math.pi * k * (k - 1.0) / harmonics
        if joint == 0
        else math.pi * k * (k + 1.0) / harmonics + 0.5 * math.pi
    )
    amplitude = 1.0 / np.sqrt(k)
    c = amplitude * np.cos(phase)
    d = amplitude * np.sin(phase)
    w = 2.0 * math.pi * k / period
    c = c - c.mean()
    d = d - w * (w @ d) / (w @ w)
    return c, d


def _profiles(
    c: FloatArray, d: FloatArray, period: float, tau: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Unscaled (q - start, q', q'') of one joint at times ``tau`` (s), each shape tau.shape."""
    w = 2.0 * math.pi * np.arange(1, c.size + 1, dtype=np.float64) / period
    angle = np.multiply.outer(tau, w)
    sin, cos = np.sin(angle), np.cos(angle)
    position = (sin * (c / w) + (1.0 - cos) * (d / w)).sum(axis=-1)
    velocity = (cos * c + sin * d).sum(axis=-1)
    acceleration = (-sin * (c * w) + cos * (d * w)).sum(axis=-1)
    return position, velocity, acceleration


@dataclass(frozen=True)
class ExcitationReference(_Sampled):
    """Finite Fourier series per joint within joint, velocity, acceleration and torque limits.

    Attributes:
        period: Base period T of the series (s), > 0.
        harmonics: Number of harmonics per joint (base frequency 1/T up to harmonics/T), integer >= 3.
        periods: Number of whole periods run, integer >= 1.
        start_time: Time the excitation starts (s), >= 0; at rest at ``start`` before and after it.
        start: Rest position at both ends per joint (rad), finite, inside +-position_limit.
        position_limit: |q_d| bound per joint (rad), > 0.
        velocity_limit: |q_d'| bound per joint (rad/s), > 0.
        acceleration_limit: |q_d''| bound per joint (rad/s^2), > 0.
        torque_limit: Bound on the nominal model's torque (``SMMParameters()``) along q_d (N m), > 0.
    """

    period: float = field(default=5.0, metadata=above(0.0))
    harmonics: int = field(default=5, metadata=at_least(3))
    periods: int = field(default=2, metadata=at_least(1))
    start_time: float = field(default=0.5, metadata=at_least(0.0))
    start: tuple[float, float] = field(default=(0.0, 0.0), metadata=no_range())
    position_limit: tuple[float, float] = field(default=(1.0, 0.785), metadata=above(0.0))
    velocity_limit: tuple[float, float] = field(default=(2.0, 2.0), metadata=above(0.0))
    acceleration_limit: tuple[float, float] = field(default=(12.0, 12.0), metadata=above(0.0))
    torque_limit: tuple[float, float] = field(default=(3.0, 3.0), metadata=above(0.0))
    _coefficients: tuple[tuple[float, ...], ...] = field(init=False, repr=False, compare=False)
    _scale: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        check_bounds(self)
        if any(abs(q) >= limit for q, limit in zip(self.start, self.position_limit, strict=True)):
            raise ValueError(f"start {self.start!r} must lie inside +-position_limit {self.position_limit!r}")
        shapes = [_shape(self.harmonics, joint, self.period) for joint in (0, 1)]
        object.__setattr__(
            self, "_coefficients", tuple(tuple(part.tolist()) for shape in shapes for part in shape)
        )
        object.__setattr__(self, "_scale", self._design_scale(shapes))

    @property
    def duration(self) -> float:
        """Time at which the excitation has ended, start_time + periods T (s)."""
        return self.start_time + self.periods * self.period

    @property
    def scale(self) -> float:
        """The designed scale s (rad/s per unit of the shape)."""
        return self._scale

    def _grid_profiles(self, shapes: list[tuple[FloatArray, FloatArray]]) -> FloatArray:
        """Unscaled (q - start, q', q'') on the design grid, shape (_GRID, 3, 2)."""
        tau = np.arange(_GRID, dtype=np.float64) * (self.period / _GRID)
        joints = [_profiles(c, d, self.period, tau) for c, d in shapes]
        return np.stack([np.stack(rows, axis=-1) for rows in zip(*joints, strict=True)], axis=1)

    def _design_scale(self, shapes: list[tuple[FloatArray, FloatArray]]) -> float:
        profiles = self._grid_profiles(shapes)
        start = np.asarray(self.start)
        limit = np.asarray(self.position_limit)
        bounds = [
            *((limit - start) / np.maximum(profiles[:, 0, :].max(axis=0), 1e-300)),
            *((limit + start) / np.maximum(-profiles[:, 0, :].min(axis=0), 1e-300)),
            *(np.asarray(self.velocity_limit) / np.abs(profiles[:, 1, :]).max(axis=0)),
            *(np.asarray(self.acceleration_limit) / np.abs(profiles[:, 2, :]).max(axis=0)),
        ]
        kinematic = float(min(bounds))
        params = SMMParameters()
        torque_limit = np.asarray(self.torque_limit)

        def within(scale: float) -> bool:
            torque = inverse_dynamics(
                start + scale * profiles[:, 0, :],
                scale * profiles[:, 1, :],
                scale * profiles[:, 2, :],
                params,
            )
            return bool(np.all(np.abs(torque) <= torque_limit))

        if not within(0.0):
            raise ValueError(
                f"torque_limit {self.torque_limit!r} N m is below the nominal torque "
                f"to hold start {self.start!r}"
            )
        if within(kinematic):
            return _MARGIN * kinematic
        low, high = 0.0, kinematic
        for _ in range(_BISECTIONS):
            middle = 0.5 * (low + high)
            low, high = (middle, high) if within(middle) else (low, middle)
        return _MARGIN * low

    def rows(self, t: float) -> Rows:
        """Position (rad), velocity (rad/s), acceleration (rad/s^2) at time t (s), as float pairs."""
        tau = t - self.start_time
        start_a, start_b = self.start
        if not 0.0 < tau < self.periods * self.period:
            return ((float(start_a), float(start_b)), (0.0, 0.0), (0.0, 0.0))
        c_a, d_a, c_b, d_b = self._coefficients
        base = 2.0 * math.pi / self.period
        scale = self._scale
        values = [0.0] * 6
        for index in range(self.harmonics):
            w = base * (index + 1)
            sine, cosine = math.sin(w * tau), math.cos(w * tau)
            for joint, (c, d) in enumerate(((c_a[index], d_a[index]), (c_b[index], d_b[index]))):
                values[joint] += (c * sine + d * (1.0 - cosine)) / w
                values[2 + joint] += c * cosine + d * sine
                values[4 + joint] += w * (d * cosine - c * sine)
        return (
            (start_a + scale * values[0], start_b + scale * values[1]),
            (scale * values[2], scale * values[3]),
            (scale * values[4], scale * values[5]),
        )

    def crest_factor(self) -> tuple[float, float]:
        """Peak over RMS of each joint's velocity q_d' over one period (dimensionless, sqrt(2) for a sine)."""
        velocity = self._grid_profiles(self._shape_arrays())[:, 1, :]
        return tuple(  # type: ignore[return-value]
            float(np.abs(velocity[:, joint]).max() / np.sqrt(np.mean(velocity[:, joint] ** 2)))
            for joint in (0, 1)
        )

    def _shape_arrays(self) -> list[tuple[FloatArray, FloatArray]]:
        c_a, d_a, c_b, d_b = (np.asarray(part) for part in self._coefficients)
        return [(c_a, d_a), (c_b, d_b)]
