"""Mamdani fuzzy inference as SPEC section 4 defines it (paper Section III.B-C, eq. 17).

Membership functions, linguistic variables, rule evaluation (min AND, min implication, max aggregation)
and the exact centroid of the sampled aggregate. The precomputed tables are in :mod:`fuzzy_tables`, the
batched evaluation every control step uses (and :func:`~smm_controller.fuzzy_batch.evaluate_system` for one
system) in :mod:`fuzzy_batch`, which import this module (docs/DESIGN.md, "The fuzzy engine").
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import pairwise, product
from math import exp
from typing import Protocol

import numpy as np
import numpy.typing as npt

__all__ = [
    "ZERO_AREA_FALLBACK",
    "FuzzyVariable",
    "GaussianMF",
    "Lattice",
    "MamdaniSystem",
    "MembershipFunction",
    "TriangularMF",
    "centroid",
    "centroid_weights",
    "gaussian_mf",
    "triangular_mf",
    "uniform_grid",
]

FloatArray = npt.NDArray[np.float64]

#: Defuzzified value returned when the aggregated membership has zero area (docs/DESIGN.md).
ZERO_AREA_FALLBACK = 0.0

# A uniform triangular partition: first peak, last peak, spacing, index of the last interval, and per
# interval (left peak, width of its falling side, right label's left foot, width of its rising side).
Lattice = tuple[float, float, float, int, tuple[tuple[float, float, float, float], ...]]


def _require_finite(name: str, value: float) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")


def triangular_mf(x: npt.ArrayLike, a: float, b: float, c: float) -> FloatArray:
    """Triangular membership max(0, min((x - a)/(b - a), (c - x)/(c - b))).

    Args:
        x: Points of the universe, any shape.
        a: Left foot (membership 0), a < b.
        b: Peak (membership 1).
        c: Right foot (membership 0), c > b.

    Returns:
        Membership degrees in [0, 1], same shape as ``x``.
    """
    points = np.asarray(x, dtype=np.float64)
    rising = (points - a) / (b - a)
    falling = (c - points) / (c - b)
    return np.maximum(0.0, np.minimum(rising, falling))


def gaussian_mf(x: npt.ArrayLike, mean: float, sigma: float) -> FloatArray:
    """Gaussian membership exp(-(x - mean)^2 / (2 sigma^2)).

    Args:
        x: Points of the universe, any shape.
        mean: Centre (membership 1).
        sigma: Standard deviation, > 0.

    Returns:
        Membership degrees in (0, 1], same shape as ``x``.
    """
    points = np.asarray(x, dtype=np.float64)
    return np.exp(-((points - mean) ** 2) / (2.0 * sigma * sigma))


class MembershipFunction(Protocol):
    """A membership function evaluated on scalars (per step) and on arrays (grids, plots)."""

    def degree(self, x: float) -> float:
        """Membership degree of one crisp value."""
        ...

    def sample(self, x: npt.ArrayLike) -> FloatArray:
        """Membership degrees of an array of values."""
        ...


@dataclass(frozen=True)
class TriangularMF:
    """Triangle with feet ``a``, ``c`` and peak ``b`` (a < b < c); see :func:`triangular_mf`."""

    a: float
    b: float
    c: float

    def __post_init__(self) -> None:
        for name in ("a", "b", "c"):
            _require_finite(name, getattr(self, name))
        if not self.a < self.b < self.c:
            raise ValueError(f"TriangularMF needs a < b < c, got a={self.a!r}, b={self.b!r}, c={self.c!r}")

    def degree(self, x: float) -> float:
        """Membership degree of one crisp value (same formula as :func:`triangular_mf`)."""
        return max(0.0, min((x - self.a) / (self.b - self.a), (self.c - x) / (self.c - self.b)))

    def sample(self, x: npt.ArrayLike) -> FloatArray:
        """Membership degrees of an array of values."""
        return triangular_mf(x, self.a, self.b, self.c)


@dataclass(frozen=True)
class GaussianMF:
    """Gaussian with centre ``mean`` and standard deviation ``sigma`` > 0; see :func:`gaussian_mf`."""

    mean: float
    sigma: float

    def __post_init__(self) -> None:
        _require_finite("mean", self.mean)
        _require_finite("sigma", self.sigma)
        if self.sigma <= 0.0:
            raise ValueError(f"sigma must be > 0, got {self.sigma!r}")

    def degree(self, x: float) -> float:
        """Membership degree of one crisp value (same formula as :func:`gaussian_mf`)."""
        return math.exp(-((x - self.mean) ** 2) / (2.0 * self.sigma * self.sigma))

    def sample(self, x: npt.ArrayLike) -> FloatArray:
        """Membership degrees of an array of values."""
        return gaussian_mf(x, self.mean, self.sigma)


class FuzzyVariable:
    """A linguistic variable: ordered labels, one membership function each.

    If the MFs are triangles forming a uniform partition (peaks equally spaced and every triangle's
    feet at its neighbours' peaks), at most two adjacent labels are non-zero at any point and
    :meth:`active` only evaluates those two (equal to evaluating all labels up to rounding). If all
    MFs are Gaussian, :meth:`active` evaluates them inline (bit-identical to GaussianMF.degree).

    Args:
        labels: Label names, e.g. ("NB", ..., "PB").
        mfs: One membership function per label.
    """

    def __init__(self, labels: Sequence[str], mfs: Sequence[MembershipFunction]) -> None:
        if len(labels) == 0 or len(labels) != len(mfs):
            raise ValueError(
                f"labels and mfs must be non-empty and of equal length, got {len(labels)} labels "
                f"and {len(mfs)} mfs"
            )
        if len(set(labels)) != len(labels):
            raise ValueError(f"labels must be unique, got {tuple(labels)!r}")
        self.labels: tuple[str, ...] = tuple(labels)
        self.mfs: tuple[MembershipFunction, ...] = tuple(mfs)
        self._index = {label: i for i, label in enumerate(self.labels)}
        self._sides: list[tuple[float, float, float, float]] = []
        self._lattice = self._uniform_triangle_lattice()
        # All-Gaussian variables: (index, mean, 2 sigma^2) for an inlined GaussianMF.degree.
        self._gaussians = (
            [
                (i, mf.mean, 2.0 * mf.sigma * mf.sigma)
                for i, mf in enumerate(self.mfs)
                if isinstance(mf, GaussianMF)
            ]
            if all(isinstance(mf, GaussianMF) for mf in self.mfs)
            else None
        )

    def _uniform_triangle_lattice(self) -> tuple[float, float, float] | None:
        if len(self.mfs) < 2 or not all(isinstance(mf, TriangularMF) for mf in self.mfs):
            return None
        triangles = [mf for mf in self.mfs if isinstance(mf, TriangularMF)]
        spacing = triangles[1].b - triangles[0].b
        tolerance = 1e-12 * max(1.0, abs(spacing))
        for i, tri in enumerate(triangles):
            expected_peak = triangles[0].b + i * spacing
            if (
                abs(tri.b - expected_peak) > tolerance
                or abs(tri.b - tri.a - spacing) > tolerance
                or abs(tri.c - tri.b - spacing) > tolerance
            ):
                return None
        # Between peaks k and k+1 only labels k (falling side) and k+1 (rising side) are non-zero.
        self._sides = [
            (left.c, left.c - left.b, right.a, right.b - right.a) for left, right in pairwise(triangles)
        ]
        return triangles[0].b, triangles[-1].b, spacing

    def index(self, label: str) -> int:
        """Position of ``label`` in :attr:`labels` (ValueError if unknown)."""
        try:
            return self._index[label]
        except KeyError:
            raise ValueError(f"unknown label {label!r}; labels are {self.labels!r}") from None

    def memberships(self, x: float) -> tuple[float, ...]:
        """Membership degree of ``x`` in every label, in label order."""
        return tuple(mf.degree(x) for mf in self.mfs)

    def _lattice_data(self) -> Lattice | None:
        """(first peak, last peak, spacing, last interval index, sides) of a uniform partition, or None."""
        if self._lattice is None:
            return None
        return (*self._lattice, len(self._sides) - 1, tuple(self._sides))

    def lattice_pair(self, x: float) -> tuple[int, float, float] | None:
        """On a uniform triangular partition: (k, degree of label k, degree of label k + 1) at ``x``.

        Every other label is zero at ``x``. Only the falling side of label k and the rising side of
        label k + 1 are evaluated; they equal the full triangle formula up to rounding (within a few
        ulps of a peak the interval found by the floor may be the neighbouring one, whence the clamp
        to 1; memberships of order 1e-16 that rounding may leave on a third label are dropped, and a
        degree that rounding leaves at or below 0 is 0.0).

        Returns:
            The pair, or None if the MFs are no uniform triangular partition or ``x`` lies outside
            their peaks (or is NaN).
        """
        lattice = self._lattice
        if lattice is None or not lattice[0] <= x <= lattice[1]:
            return None
        left = min(int((x - lattice[0]) // lattice[2]), len(self._sides) - 1)
        peak_left, falling_width, foot_right, rising_width = self._sides[left]
        falling = min((peak_left - x) / falling_width, 1.0)
        rising = min((x - foot_right) / rising_width, 1.0)
        return left, (falling if falling > 0.0 else 0.0), (rising if rising > 0.0 else 0.0)

    def active(self, x: float) -> list[tuple[int, float]]:
        """(label index, degree) for every label that can be non-zero at ``x``, in label order.

        On a uniform triangular partition these are the non-zero labels of :meth:`lattice_pair`.
        """
        pair = self.lattice_pair(x)
        if pair is not None:
            left, falling, rising = pair
            if falling > 0.0:
                if rising > 0.0:
                    return [(left, falling), (left + 1, rising)]
                return [(left, falling)]
            return [(left + 1, rising)]  # falling <= 0 leaves rising >= 1 - rounding: they add up to 1
        if self._gaussians is not None:
            # Same expression as GaussianMF.degree; every label is active (a degree that underflows
            # to 0.0 is returned too: it fires no rule).
            return [(i, exp(-((x - mean) ** 2) / width)) for i, mean, width in self._gaussians]
        pairs = []
        for i, mf in enumerate(self.mfs):
            degree = mf.degree(x)
            if degree > 0.0:
                pairs.append((i, degree))
        return pairs


def uniform_grid(universe: tuple[float, float], grid_points: int) -> FloatArray:
    """Uniform grid of ``grid_points`` points over ``universe`` (both ends included)."""
    low, high = universe
    if grid_points < 3:
        raise ValueError(f"grid_points must be >= 3, got {grid_points!r}")
    if not low < high:
        raise ValueError(f"universe must satisfy low < high, got {universe!r}")
    return np.linspace(low, high, grid_points)


def centroid_weights(grid: npt.ArrayLike) -> FloatArray:
    """Weights giving area and first moment of the piecewise-linear interpolation of samples.

    For samples ``m`` on the increasing ``grid``, ``m @ W[:, 0]`` is the integral of the
    piecewise-linear interpolation and ``m @ W[:, 1]`` the integral of x times it. On a segment
    [x0, x1] of width d with end values m0, m1: area = d (m0 + m1)/2 and
    moment = x0 d (m0 + m1)/2 + d^2 (m0/6 + m1/3).

    Args:
        grid: Strictly increasing points, shape (n,), n >= 2.

    Returns:
        Weights, shape (n, 2): column 0 area, column 1 moment.
    """
    points = np.asarray(grid, dtype=np.float64)
    if points.ndim != 1 or points.size < 2 or not np.all(np.diff(points) > 0.0):
        raise ValueError("grid must be a strictly increasing 1-D array of at least 2 points")
    left = points[:-1]
    width = np.diff(points)
    weights = np.zeros((points.size, 2))
    weights[:-1, 0] += 0.5 * width
    weights[1:, 0] += 0.5 * width
    weights[:-1, 1] += 0.5 * left * width + width * width / 6.0
    weights[1:, 1] += 0.5 * left * width + width * width / 3.0
    return weights


def centroid(grid: npt.ArrayLike, membership: npt.ArrayLike) -> float:
    """Exact centroid of the piecewise-linear interpolation of ``membership`` on ``grid`` (eq. 17).

    Args:
        grid: Strictly increasing points, shape (n,).
        membership: Non-negative samples, shape (n,).

    Returns:
        The centroid, or :data:`ZERO_AREA_FALLBACK` if the area is zero.
    """
    area, moment = np.asarray(membership, dtype=np.float64) @ centroid_weights(grid)
    return float(moment / area) if area > 0.0 else ZERO_AREA_FALLBACK


class MamdaniSystem:
    """One Mamdani rule base (min AND, min implication, max aggregation, centroid).

    Args:
        inputs: Input variables, in the order of the crisp inputs and of each rule's antecedent.
        outputs: Output variables (each an MF family over ``universe``).
        rules: Antecedent labels (one per input) -> consequent labels (one per output). Input
            combinations without a rule do not fire.
        grid_points: Points of the uniform defuzzification grid over ``universe``, >= 3.
        universe: Output universe (low, high).
    """

    def __init__(
        self,
        inputs: Sequence[FuzzyVariable],
        outputs: Sequence[FuzzyVariable],
        rules: Mapping[tuple[str, ...], tuple[str, ...]],
        grid_points: int = 201,
        universe: tuple[float, float] = (-1.0, 1.0),
    ) -> None:
        if not inputs or not outputs:
            raise ValueError("a MamdaniSystem needs at least one input and one output variable")
        self.inputs: tuple[FuzzyVariable, ...] = tuple(inputs)
        self.outputs: tuple[FuzzyVariable, ...] = tuple(outputs)
        self.grid: FloatArray = uniform_grid(universe, grid_points)
        self.universe = universe
        self._radix = [len(var.labels) for var in self.inputs]
        self.n_labels = max(len(var.labels) for var in self.outputs)
        self._n_strengths = len(self.outputs) * self.n_labels
        # Per flattened antecedent combination: the strength slots (o * n_labels + label) it sets.
        targets: list[tuple[int, ...]] = [() for _ in range(math.prod(self._radix))]
        for antecedent, consequent in rules.items():
            if len(antecedent) != len(self.inputs) or len(consequent) != len(self.outputs):
                raise ValueError(
                    f"rule {antecedent!r} -> {consequent!r} does not match {len(self.inputs)} "
                    f"inputs and {len(self.outputs)} outputs"
                )
            flat = self._flat_index(
                [var.index(label) for var, label in zip(self.inputs, antecedent, strict=True)]
            )
            targets[flat] = tuple(
                o * self.n_labels + var.index(label)
                for o, (var, label) in enumerate(zip(self.outputs, consequent, strict=True))
            )
        self._targets = targets
        # Output MF samples, shape (n_labels, n_outputs, grid); missing labels are zero rows.
        samples = np.zeros((self.n_labels, len(self.outputs), self.grid.size))
        for o, var in enumerate(self.outputs):
            for label, mf in enumerate(var.mfs):
                samples[label, o] = mf.sample(self.grid)
        self.output_samples: FloatArray = samples
        self.output_samples.flags.writeable = False

    def _flat_index(self, indices: Sequence[int]) -> int:
        flat = 0
        for radix, i in zip(self._radix, indices, strict=True):
            flat = flat * radix + i
        return flat

    def label_strengths(self, x: Sequence[float]) -> list[float]:
        """Implication level of every output label: max firing strength of the rules concluding it.

        Args:
            x: One crisp value per input variable.

        Returns:
            Flat list, ``strengths[o * n_labels + label]`` for output o (labels padded to
            ``n_labels`` with 0.0).
        """
        strengths = [0.0] * self._n_strengths
        self.accumulate_strengths(x, strengths, self._targets)
        return strengths

    def slot_table(self, slot_of: Sequence[int]) -> list[tuple[int, ...]]:
        """Rule targets re-indexed for a caller's layout.

        Args:
            slot_of: Destination index for each local slot ``o * n_labels + label``.

        Returns:
            Per flattened antecedent combination, the destination slots it sets.
        """
        return [tuple(slot_of[slot] for slot in slots) for slots in self._targets]

    def accumulate_strengths(
        self, x: Sequence[float], out: list[float], targets: Sequence[tuple[int, ...]]
    ) -> None:
        """Raises ``out[slot]`` to the firing strength of every rule concluding that slot.

        Rule firing is AND = min over the antecedent memberships; a label's implication level is the
        max over its rules. Only active labels (membership > 0) are visited.

        Args:
            x: One crisp value per input variable.
            out: Strength slots, initialised to 0.0 by the caller.
            targets: Slots set by each flattened antecedent combination (see :meth:`slot_table`).
        """
        # Hot path (every control step): explicit comparisons are faster than builtin max/min calls.
        n_inputs = len(self.inputs)
        if len(x) != n_inputs:
            raise ValueError(f"expected {n_inputs} inputs, got {len(x)}")
        if n_inputs == 2:
            second = self.inputs[1].active(x[1])
            radix = self._radix[1]
            for i, degree_i in self.inputs[0].active(x[0]):
                base = i * radix
                for j, degree_j in second:
                    firing = degree_i if degree_i < degree_j else degree_j
                    for slot in targets[base + j]:
                        if firing > out[slot]:  # noqa: PLR1730
                            out[slot] = firing
            return
        if n_inputs == 1:
            variable = self.inputs[0]
            value = x[0]
            gaussians = variable._gaussians
            if gaussians is not None:
                # FuzzyVariable.active inlined for Gaussian labels (same expression).
                for i, mean, width in gaussians:
                    firing = exp(-((value - mean) ** 2) / width)
                    for slot in targets[i]:
                        if firing > out[slot]:  # noqa: PLR1730
                            out[slot] = firing
                return
            for i, firing in variable.active(value):
                for slot in targets[i]:
                    if firing > out[slot]:  # noqa: PLR1730
                        out[slot] = firing
            return
        for combination in product(*(var.active(v) for var, v in zip(self.inputs, x, strict=True))):
            flat = 0
            firing = 1.0
            for radix, (i, degree) in zip(self._radix, combination, strict=True):
                flat = flat * radix + i
                firing = min(firing, degree)
            for slot in targets[flat]:
                if firing > out[slot]:  # noqa: PLR1730
                    out[slot] = firing

    def aggregated_membership(self, x: Sequence[float]) -> FloatArray:
        """Aggregated output membership sampled on :attr:`grid`, shape (n_outputs, grid_points)."""
        strengths = np.reshape(self.label_strengths(x), (len(self.outputs), self.n_labels))
        clipped = np.minimum(strengths.T[:, :, None], self.output_samples)
        return np.asarray(clipped.max(axis=0), dtype=np.float64)
