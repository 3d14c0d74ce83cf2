"""Mamdani fuzzy inference engine (SPEC section 4, paper Section III.B-C, eq. 17).

Definition implemented here, exactly:

* fuzzification: each crisp input is evaluated on the membership functions (MFs) of its variable;
* rule firing strength: AND = min over the rule's antecedent memberships;
* implication: min (each output label's MF is clipped at the largest firing strength of the rules that
  conclude that label, i.e. aggregation = max);
* aggregation: max over the clipped output MFs;
* defuzzification: centroid (eq. 17) of the aggregated membership sampled on a uniform grid over the
  output universe, taken as the *exact* centroid of the piecewise-linear interpolation of the samples.
  Area and first moment of that interpolation are linear in the samples, so both are one dot product
  with a precomputed weight vector (:func:`centroid_weights`). This is what scikit-fuzzy's
  ``defuzz(x, mfx, "centroid")`` computes for the same samples.

Zero aggregated area cannot happen for a complete rule base with inputs clipped to the input
universe (at least one rule fires with positive strength and the Gaussian output MFs are positive
everywhere). It is still guarded: the defuzzified value is then :data:`ZERO_AREA_FALLBACK` (0.0, the
"no correction" value of the normalised outputs used here).

Speed: a control step needs several small inferences (per joint, per output). :class:`MamdaniBatch`
evaluates the rule bases in plain Python (only the labels that are active, at most two per input for a
uniform triangular partition) and does the aggregation and defuzzification of all joints and outputs
in four vectorised numpy calls, whose cost grows with the number of sampled MFs they touch. For
complete rule bases of two inputs on uniform triangular partitions (the fuzzy PD schedule) at most the
2 x 2 rules around the inputs fire, so only the output MFs those rules conclude are clipped (max over
them per output; min and max commute, so the aggregate is bit for bit the one over all labels). When
one input sits on a peak or at an end of its universe (often: a saturated error rate), only one or two
rules fire and their strengths add up to 1; then each output is one clipped label or the max of two,
whose centroid :class:`LabelPairCentroids` evaluates from tables without array operations, equal to
the sums over the grid up to rounding (a few 1e-16; tests pin 1e-13 against the dense evaluation).

A rule base of one input with Gaussian labels (the FLESO bandwidth) needs no array operation at all:
between consecutive breakpoints of the input, where a membership crosses a sampled output value or
another membership, which label wins each grid point and whether it is clipped stay the same, so area
and moment of the aggregate are a constant plus a fixed combination of the input memberships
(:class:`SingleInputCentroids`). A bisection finds the interval; the result equals the sum over the
grid up to rounding.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left, bisect_right
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from itertools import combinations, pairwise, product
from math import exp
from typing import Protocol

import numpy as np
import numpy.typing as npt

__all__ = [
    "ZERO_AREA_FALLBACK",
    "FuzzyVariable",
    "GaussianMF",
    "LabelPairCentroids",
    "MamdaniBatch",
    "MamdaniSystem",
    "MembershipFunction",
    "SingleInputCentroids",
    "TriangularMF",
    "centroid",
    "centroid_weights",
    "gaussian_mf",
    "triangular_mf",
    "uniform_grid",
]

FloatArray = npt.NDArray[np.float64]

#: Defuzzified value returned when the aggregated membership has zero area (see module docstring).
ZERO_AREA_FALLBACK = 0.0

# Two rules of a uniform triangular partition with the other input on a peak have strengths adding up
# to 1 up to rounding; LabelPairCentroids assumes that sum.
_UNIT_SUM_TOLERANCE = 1e-9

# A uniform triangular partition: first peak, last peak, spacing, index of the last interval, and per
# interval (left peak, width of its falling side, right label's left foot, width of its rising side).
_Lattice = tuple[float, float, float, int, tuple[tuple[float, float, float, float], ...]]


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

    def _lattice_data(self) -> _Lattice | None:
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

    def evaluate(self, x: Sequence[float]) -> tuple[float, ...]:
        """Crisp outputs for one crisp input vector (one value per output variable)."""
        return tuple(MamdaniBatch([self]).evaluate([x])[0])


# Per interval of the input, per output: constant area, constant moment, and (input label, area
# coefficient, moment coefficient) for each input label whose membership clips the aggregate somewhere.
_IntervalCoefficients = tuple[tuple[float, float, tuple[tuple[int, float, float], ...]], ...]


class SingleInputCentroids:
    """Exact centroids of a rule base with one input whose labels are Gaussian, piecewise in the input.

    Rule a (input label a) fires with mu_a(x); output label l is clipped at the largest mu_a of the
    rules that conclude it, and the aggregate is the max over the labels of min(level, sampled MF). The
    outcome of every comparison in that evaluation (a membership against a sampled value, against
    another membership, or two sampled values) can only change where mu_a(x) equals a sampled value or
    mu_b(x). Between consecutive such breakpoints each grid point's aggregate is either a fixed sample
    or a fixed mu_a(x), so area and moment (:func:`centroid_weights`) are a constant plus
    sum_a mu_a(x) times a coefficient. These are computed once at interval midpoints; an evaluation is
    a bisection and a few products, no array operation. The input range covered is [smallest mean,
    largest mean] of the input labels.

    Args:
        gaussians: (mean, 2 sigma^2) of each input label, in label order.
        consequents: Per input label, per output, the output label its rule concludes, or -1 (no rule).
        samples: Output MFs on the grid, shape (outputs, output labels, grid points), non-negative.
        weights: :func:`centroid_weights` of the grid, shape (grid points, 2).
    """

    _CHUNK = 512

    def __init__(
        self,
        gaussians: Sequence[tuple[float, float]],
        consequents: Sequence[Sequence[int]],
        samples: npt.ArrayLike,
        weights: npt.ArrayLike,
    ) -> None:
        self.gaussians: tuple[tuple[float, float], ...] = tuple((float(m), float(w)) for m, w in gaussians)
        self._consequents = tuple(tuple(int(label) for label in row) for row in consequents)
        sample_array = np.array(samples, dtype=np.float64)
        weight_array = np.array(weights, dtype=np.float64)
        if sample_array.ndim != 3 or weight_array.shape != (sample_array.shape[2], 2):
            raise ValueError(
                "samples must have shape (outputs, labels, n) and weights shape (n, 2), got "
                f"{sample_array.shape} and {weight_array.shape}"
            )
        if len(self._consequents) != len(self.gaussians) or any(
            len(row) != sample_array.shape[0] for row in self._consequents
        ):
            raise ValueError(
                f"consequents must give one output label per input label ({len(self.gaussians)}) and output "
                f"({sample_array.shape[0]}), got rows of lengths {[len(row) for row in self._consequents]}"
            )
        means = np.array([mean for mean, _ in self.gaussians])
        self.low = float(means.min())
        self.high = float(means.max())
        self.breakpoints: list[float] = self._breakpoints(sample_array).tolist()
        edges = np.array([self.low, *self.breakpoints, self.high])
        midpoints = 0.5 * (edges[:-1] + edges[1:])
        self._coefficients: list[_IntervalCoefficients] = []
        for start in range(0, midpoints.size, self._CHUNK):
            self._coefficients.extend(
                self._interval_coefficients(
                    midpoints[start : start + self._CHUNK], sample_array, weight_array
                )
            )

    def _breakpoints(self, samples: FloatArray) -> FloatArray:
        values = np.unique(samples[samples > 0.0])
        values = values[values <= 1.0]
        candidates: list[FloatArray] = []
        for mean, width in self.gaussians:
            distance = np.sqrt(-width * np.log(values))
            candidates.extend((mean - distance, mean + distance))
        for (mean_a, width_a), (mean_b, width_b) in combinations(self.gaussians, 2):
            # (x - mean_a)^2 / width_a = (x - mean_b)^2 / width_b
            quadratic = width_b - width_a
            linear = -2.0 * (mean_a * width_b - mean_b * width_a)
            constant = mean_a * mean_a * width_b - mean_b * mean_b * width_a
            if quadratic == 0.0:
                if linear != 0.0:
                    candidates.append(np.array([-constant / linear]))
            else:
                discriminant = linear * linear - 4.0 * quadratic * constant
                if discriminant >= 0.0:
                    root = math.sqrt(discriminant)
                    candidates.append(np.array([(-linear - root), (-linear + root)]) / (2.0 * quadratic))
        points = np.unique(np.concatenate(candidates))
        return points[(points > self.low) & (points < self.high)]

    def _interval_coefficients(
        self, midpoints: FloatArray, samples: FloatArray, weights: FloatArray
    ) -> list[_IntervalCoefficients]:
        means = np.array([mean for mean, _ in self.gaussians])
        widths = np.array([width for _, width in self.gaussians])
        memberships = np.exp(-((midpoints[:, None] - means) ** 2) / widths)  # (intervals, input labels)
        n_intervals, n_inputs = memberships.shape
        per_output = []
        for o, output_samples in enumerate(samples):
            n_labels, n_points = output_samples.shape
            level = np.zeros((n_intervals, n_labels))
            rule = np.full((n_intervals, n_labels), -1)
            for a in range(n_inputs):
                label = self._consequents[a][o]
                if label >= 0:
                    higher = memberships[:, a] > level[:, label]
                    level[higher, label] = memberships[higher, a]
                    rule[higher, label] = a
            clipped = np.minimum(level[:, :, None], output_samples[None, :, :])
            winner = clipped.argmax(axis=1)  # (intervals, points)
            points = np.arange(n_points)
            winner_sample = output_samples[winner, points]
            winner_level = np.take_along_axis(level, winner, axis=1)
            winner_rule = np.take_along_axis(rule, winner, axis=1)
            is_clipped = winner_level < winner_sample
            constant = np.where(is_clipped, 0.0, winner_sample) @ weights  # (intervals, 2)
            by_rule = np.zeros((n_intervals, n_inputs, 2))
            for a in range(n_inputs):
                by_rule[:, a, :] = (is_clipped & (winner_rule == a)).astype(np.float64) @ weights
            per_output.append((constant, by_rule))
        result = []
        for k in range(n_intervals):
            result.append(
                tuple(
                    (
                        float(constant[k, 0]),
                        float(constant[k, 1]),
                        tuple(
                            (a, float(by_rule[k, a, 0]), float(by_rule[k, a, 1]))
                            for a in range(n_inputs)
                            if by_rule[k, a, 0] > 0.0  # else no point is clipped by rule a
                        ),
                    )
                    for constant, by_rule in per_output
                )
            )
        return result

    def evaluate(self, x: float) -> list[float] | None:
        """Crisp value of every output at input ``x``; None outside [low, high] (or for NaN)."""
        if not self.low <= x <= self.high:
            return None
        gaussians = self.gaussians
        crisp = []
        for constant_area, constant_moment, clipping in self._coefficients[bisect_right(self.breakpoints, x)]:
            area = constant_area
            moment = constant_moment
            for a, area_coefficient, moment_coefficient in clipping:
                # The same expression as GaussianMF.degree, for the labels that clip here only.
                mean, width = gaussians[a]
                membership = exp(-((x - mean) ** 2) / width)
                area += membership * area_coefficient
                moment += membership * moment_coefficient
            crisp.append(moment / area if area > 0.0 else ZERO_AREA_FALLBACK)
        return crisp


# Sorted samples of one MF and, per split index, area and moment of the samples below it and the
# area and moment weights at and above it (see LabelPairCentroids.single).
_ClipTable = tuple[list[float], list[float], list[float], list[float], list[float]]


class LabelPairCentroids:
    """Exact centroids of one clipped output label, or of the max of two whose levels add up to 1.

    One label l clipped at s: area and moment are sums over the grid of weights times min(s, MF_l[i]);
    with MF_l sorted once, the samples below s count with their value and the others with s, so each sum
    is one bisection and two prefix sums. Two labels a < b clipped at s_a and s_b = 1 - s_a (two rules of
    a uniform triangular partition, one input fixed on a peak): every comparison in
    max(min(s_a, MF_a[i]), min(s_b, MF_b[i])) changes only where s_a equals MF_a[i], MF_b[i],
    1 - MF_a[i], 1 - MF_b[i] or 1/2, so between these breakpoints area and moment are a constant plus
    s_a and s_b times coefficients, tabulated at interval midpoints. Both equal the sums over the grid
    up to rounding.

    Args:
        samples: Output MFs on the grid, shape (labels, grid points), non-negative.
        weights: :func:`centroid_weights` of the grid, shape (grid points, 2).
    """

    def __init__(self, samples: npt.ArrayLike, weights: npt.ArrayLike) -> None:
        sample_array = np.array(samples, dtype=np.float64)
        weight_array = np.array(weights, dtype=np.float64)
        if sample_array.ndim != 2 or weight_array.shape != (sample_array.shape[1], 2):
            raise ValueError(
                "samples must have shape (labels, n) and weights shape (n, 2), got "
                f"{sample_array.shape} and {weight_array.shape}"
            )
        self._singles = [self._clip_table(row, weight_array) for row in sample_array]
        self._pairs = {
            (a, b): self._pair_table(sample_array[a], sample_array[b], weight_array)
            for a, b in combinations(range(sample_array.shape[0]), 2)
        }

    @staticmethod
    def _clip_table(samples: FloatArray, weights: FloatArray) -> _ClipTable:
        order = np.argsort(samples, kind="stable")
        values = samples[order]
        area_weights, moment_weights = weights[order, 0], weights[order, 1]
        zero = np.zeros(1)
        return (
            values.tolist(),
            np.concatenate((zero, np.cumsum(area_weights * values))).tolist(),
            np.concatenate((np.cumsum(area_weights[::-1])[::-1], zero)).tolist(),
            np.concatenate((zero, np.cumsum(moment_weights * values))).tolist(),
            np.concatenate((np.cumsum(moment_weights[::-1])[::-1], zero)).tolist(),
        )

    @staticmethod
    def _pair_table(
        first: FloatArray, second: FloatArray, weights: FloatArray
    ) -> tuple[list[float], array[float]]:
        candidates = np.concatenate((first, second, 1.0 - first, 1.0 - second, [0.5]))
        breakpoints = np.unique(candidates[(candidates > 0.0) & (candidates < 1.0)])
        edges = np.concatenate(([0.0], breakpoints, [1.0]))
        level = 0.5 * (edges[:-1] + edges[1:])[:, None]  # the first label's level at interval midpoints
        clipped_first = np.minimum(level, first)
        clipped_second = np.minimum(1.0 - level, second)
        second_wins = clipped_second > clipped_first
        first_clipped = ~second_wins & (level < first)
        second_clipped = second_wins & (1.0 - level < second)
        constant = np.where(second_wins, second, first) * ~(first_clipped | second_clipped)
        coefficients = np.concatenate(
            (
                constant @ weights,
                first_clipped.astype(np.float64) @ weights,
                second_clipped.astype(np.float64) @ weights,
            ),
            axis=1,
        )  # per interval: area, moment, then the first's and the second's level coefficients
        return breakpoints.tolist(), array("d", coefficients.ravel().tolist())

    def single(self, label: int, level: float) -> float:
        """Centroid of min(level, MF_label) (level > 0)."""
        values, area_below, area_above, moment_below, moment_above = self._singles[label]
        split = bisect_left(values, level)
        area = area_below[split] + level * area_above[split]
        moment = moment_below[split] + level * moment_above[split]
        return moment / area if area > 0.0 else ZERO_AREA_FALLBACK

    def pair(self, first: int, first_level: float, second: int, second_level: float) -> float:
        """Centroid of the max of two distinct clipped labels whose levels add up to 1."""
        if first > second:
            first, first_level, second, second_level = second, second_level, first, first_level
        breakpoints, coefficients = self._pairs[first, second]
        at = 6 * bisect_right(breakpoints, first_level)
        area = coefficients[at] + first_level * coefficients[at + 2] + second_level * coefficients[at + 4]
        moment = (
            coefficients[at + 1] + first_level * coefficients[at + 3] + second_level * coefficients[at + 5]
        )
        return moment / area if area > 0.0 else ZERO_AREA_FALLBACK


@lru_cache(maxsize=16)
def _label_pair_centroids(samples: bytes, labels: int, weights: bytes) -> LabelPairCentroids:
    """One table set per output MF family and grid in the process (tens of ms to build)."""
    return LabelPairCentroids(
        np.frombuffer(samples, dtype=np.float64).reshape(labels, -1),
        np.frombuffer(weights, dtype=np.float64).reshape(-1, 2),
    )


@lru_cache(maxsize=16)
def _single_input_centroids(
    gaussians: tuple[tuple[float, float], ...],
    consequents: tuple[tuple[int, ...], ...],
    samples: bytes,
    shape: tuple[int, int, int],
    weights: bytes,
) -> SingleInputCentroids:
    """One table per rule base and grid in the process (building one takes a few tens of ms)."""
    return SingleInputCentroids(
        gaussians,
        consequents,
        np.frombuffer(samples, dtype=np.float64).reshape(shape),
        np.frombuffer(weights, dtype=np.float64).reshape(-1, 2),
    )


class MamdaniBatch:
    """Evaluates several rule bases that share output MFs and grid, in one vectorised pass.

    Typical use: one system per joint (alpha, beta), each with its own rule table; all joints and all
    outputs are aggregated and defuzzified together.

    Args:
        systems: Rule bases with identical output MF samples (same grid and output variables).
    """

    def __init__(self, systems: Sequence[MamdaniSystem]) -> None:
        if not systems:
            raise ValueError("MamdaniBatch needs at least one system")
        first = systems[0]
        for system in systems[1:]:
            if system.output_samples.shape != first.output_samples.shape or not np.array_equal(
                system.output_samples, first.output_samples
            ):
                raise ValueError("all systems of a MamdaniBatch must share output MFs and grid")
        self.systems: tuple[MamdaniSystem, ...] = tuple(systems)
        n_outputs = len(first.outputs)
        n_labels = first.n_labels
        n_rows = len(systems) * n_outputs
        self._n_outputs = n_outputs
        self._n_labels = n_labels
        self._n_rows = n_rows
        self._n_slots = n_labels * n_rows
        # Rows are (system, output) pairs. Strength slots are label-major, slot = label * rows + row,
        # so that the strengths reshape to (labels, rows, 1) and the max over labels is a reduction
        # along the leading axis.
        self._targets = [
            system.slot_table(
                [label * n_rows + s * n_outputs + o for o in range(n_outputs) for label in range(n_labels)]
            )
            for s, system in enumerate(systems)
        ]
        self._pairs = tuple(zip(self.systems, self._targets, strict=True))
        self._shape = (n_labels, n_rows, 1)
        self._samples = np.ascontiguousarray(np.concatenate([first.output_samples] * len(systems), axis=1))
        self._clipped = np.empty((n_labels, n_rows, first.grid.size))
        self._aggregated = np.empty((n_rows, first.grid.size))
        self._weights = centroid_weights(first.grid)
        self._single_input_plan = self._single_input_tables()
        self._lattice_plan = self._two_input_lattice_plan()
        if self._lattice_plan is not None:
            grid_size = first.grid.size
            # Per output, the tables for one or two clipped labels (PD: one family for both outputs).
            self._pair_centroids = [
                _label_pair_centroids(
                    np.ascontiguousarray(first.output_samples[:, o, :]).tobytes(),
                    n_labels,
                    self._weights.tobytes(),
                )
                for o in range(n_outputs)
            ]
            # Rows of _samples as one table: row label * n_rows + (system, output) row = a strength slot.
            self._sample_table = self._samples.reshape(n_labels * n_rows, grid_size)
            # Per number m of systems whose four rules fire: the firing strengths (broadcast over the
            # outputs and the grid), and per output the output MF each rule concludes, clipped in place.
            self._lattice_buffers = [
                self._lattice_buffer(m, n_outputs, grid_size) for m in range(1, len(systems) + 1)
            ]

    @staticmethod
    def _lattice_buffer(
        n_systems: int, n_outputs: int, grid_size: int
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        firing = np.zeros(n_systems * 4)
        gathered = np.zeros((n_systems * 4 * n_outputs, grid_size))
        aggregated = np.zeros((n_systems * n_outputs, grid_size))
        return (
            firing,
            firing.reshape(n_systems, 4, 1, 1),
            gathered,
            gathered.reshape(n_systems, 4, n_outputs, grid_size),
            aggregated,
            aggregated.reshape(n_systems, n_outputs, grid_size),
        )

    def _single_input_tables(self) -> tuple[SingleInputCentroids, ...] | None:
        """Per system its :class:`SingleInputCentroids`, if every system has one Gaussian input."""
        first = self.systems[0]
        n_outputs = len(first.outputs)
        n_labels = first.n_labels
        samples = np.ascontiguousarray(np.transpose(first.output_samples, (1, 0, 2)))
        tables = []
        for system in self.systems:
            gaussians = system.inputs[0]._gaussians if len(system.inputs) == 1 else None
            if gaussians is None:
                return None
            # Per input label (a rule concludes every output, in output order): output labels or -1.
            consequents = tuple(
                tuple(slot - o * n_labels for o, slot in enumerate(slots)) if slots else (-1,) * n_outputs
                for slots in system.slot_table(range(n_outputs * n_labels))
            )
            tables.append(
                _single_input_centroids(
                    tuple((mean, width) for _, mean, width in gaussians),
                    consequents,
                    samples.tobytes(),
                    (n_outputs, n_labels, first.grid.size),
                    self._weights.tobytes(),
                )
            )
        return tuple(tables)

    def _two_input_lattice_plan(
        self,
    ) -> tuple[tuple[_Lattice, _Lattice, int, list[tuple[int, ...]], list[tuple[int, ...]]], ...] | None:
        """Per system: the inputs' lattices, the second's radix, and the rules per antecedent cell.

        The rules are, per antecedent cell, the strength slots and the output labels its rule
        concludes (one per output). None unless every system has two inputs on uniform triangular
        partitions and a rule for every antecedent cell (then exactly the four cells around the inputs
        can fire).
        """
        plan = []
        n_outputs, n_labels = self._n_outputs, self._n_labels
        for system, targets in self._pairs:
            if len(system.inputs) != 2 or any(len(slots) != n_outputs for slots in targets):
                return None
            lattices = [var._lattice_data() for var in system.inputs]
            if lattices[0] is None or lattices[1] is None:
                return None
            labels = [
                tuple(slot - o * n_labels for o, slot in enumerate(slots))
                for slots in system.slot_table(range(n_outputs * n_labels))
            ]
            plan.append((lattices[0], lattices[1], len(system.inputs[1].labels), targets, labels))
        return tuple(plan)

    def _evaluate_two_input_lattice(self, inputs: Sequence[Sequence[float]]) -> list[float] | None:
        """:meth:`evaluate_flat` on the lattice plan; None if an input lies off its lattice.

        Per system only the rules of the cells around the inputs with a positive firing strength fire
        (1, 2 or 4 of them). With one or two (one input on a peak or an end), each output is taken
        from :class:`LabelPairCentroids`; with four, the concluded MFs are clipped, max-aggregated and
        defuzzified in numpy, for all such systems at once. The lattice lookup is
        :meth:`FuzzyVariable.lattice_pair` inlined (the same expressions; a test pins the result to the
        dense evaluation): this runs every control step.
        """
        assert self._lattice_plan is not None
        n_outputs = self._n_outputs
        outputs = range(n_outputs)
        pair_centroids = self._pair_centroids
        crisp = [0.0] * self._n_rows
        four_rules: list[tuple[int, list[tuple[int, float]]]] = []
        for system_index, ((first, second, radix, _, labels), x) in enumerate(
            zip(self._lattice_plan, inputs, strict=True)
        ):
            if len(x) != 2:
                return None
            x0, x1 = x
            low, high, spacing, last, sides = first
            if not low <= x0 <= high:
                return None
            i = int((x0 - low) // spacing)
            if i > last:  # noqa: PLR1730 (faster than min() here)
                i = last
            peak_left, falling_width, foot_right, rising_width = sides[i]
            degree_i = (peak_left - x0) / falling_width
            degree_i1 = (x0 - foot_right) / rising_width
            low, high, spacing, last, sides = second
            if not low <= x1 <= high:
                return None
            j = int((x1 - low) // spacing)
            if j > last:  # noqa: PLR1730 (faster than min() here)
                j = last
            peak_left, falling_width, foot_right, rising_width = sides[j]
            degree_j = (peak_left - x1) / falling_width
            degree_j1 = (x1 - foot_right) / rising_width
            # Clamp at 1 as lattice_pair does; a degree <= 0 fires no rule.
            degree_i = 1.0 if degree_i > 1.0 else degree_i
            degree_i1 = 1.0 if degree_i1 > 1.0 else degree_i1
            degree_j = 1.0 if degree_j > 1.0 else degree_j
            degree_j1 = 1.0 if degree_j1 > 1.0 else degree_j1
            # Cells (i, j), (i, j + 1), (i + 1, j), (i + 1, j + 1) with a positive AND = min.
            cell = i * radix + j
            fired = []
            if degree_i > 0.0:
                if degree_j > 0.0:
                    fired.append((cell, degree_i if degree_i < degree_j else degree_j))
                if degree_j1 > 0.0:
                    fired.append((cell + 1, degree_i if degree_i < degree_j1 else degree_j1))
            if degree_i1 > 0.0:
                if degree_j > 0.0:
                    fired.append((cell + radix, degree_i1 if degree_i1 < degree_j else degree_j))
                if degree_j1 > 0.0:
                    fired.append((cell + radix + 1, degree_i1 if degree_i1 < degree_j1 else degree_j1))
            row = system_index * n_outputs
            if len(fired) == 1:
                ((cell, level),) = fired
                for o in outputs:
                    crisp[row + o] = pair_centroids[o].single(labels[cell][o], level)
            elif len(fired) == 2 and abs(fired[0][1] + fired[1][1] - 1.0) <= _UNIT_SUM_TOLERANCE:
                (cell, level), (other_cell, other_level) = fired
                for o in outputs:
                    label, other_label = labels[cell][o], labels[other_cell][o]
                    if label == other_label:
                        crisp[row + o] = pair_centroids[o].single(label, max(level, other_level))
                    else:
                        crisp[row + o] = pair_centroids[o].pair(label, level, other_label, other_level)
            elif len(fired) == 4:
                four_rules.append((system_index, fired))
            else:
                return None  # none, or two whose sum is not 1: impossible on a partition of unity
        if four_rules:
            self._clip_and_defuzzify(four_rules, crisp)
        return crisp

    def _clip_and_defuzzify(
        self, systems: list[tuple[int, list[tuple[int, float]]]], crisp: list[float]
    ) -> None:
        """Numpy min/max/centroid of the given systems' four fired rules each."""
        assert self._lattice_plan is not None
        slots: list[int] = []
        firings: list[float] = []
        for system_index, fired in systems:
            targets = self._lattice_plan[system_index][3]
            for cell, level in fired:
                slots += targets[cell]
                firings.append(level)
        firing, firing_view, gathered, gathered_view, aggregated, aggregated_view = self._lattice_buffers[
            len(systems) - 1
        ]
        firing[:] = firings
        self._sample_table.take(slots, 0, gathered, "clip")
        np.minimum(gathered_view, firing_view, out=gathered_view)
        np.maximum.reduce(gathered_view, axis=1, out=aggregated_view)
        values = np.dot(aggregated, self._weights).tolist()
        n_outputs = self._n_outputs
        for k, (system_index, _) in enumerate(systems):
            for o in range(n_outputs):
                area, moment = values[k * n_outputs + o]
                crisp[system_index * n_outputs + o] = moment / area if area > 0.0 else ZERO_AREA_FALLBACK

    def evaluate(self, inputs: Sequence[Sequence[float]]) -> list[list[float]]:
        """Crisp outputs of every system.

        Args:
            inputs: One crisp input vector per system, in system order.

        Returns:
            ``outputs[s][o]``: crisp value of output o of system s.
        """
        crisp = self.evaluate_flat(inputs)
        n = self._n_outputs
        return [crisp[s * n : (s + 1) * n] for s in range(len(self.systems))]

    def evaluate_flat(self, inputs: Sequence[Sequence[float]]) -> list[float]:
        """Crisp outputs of every system, flat: ``outputs[s * n_outputs + o]``."""
        if len(inputs) != len(self.systems):
            raise ValueError(f"expected {len(self.systems)} input vectors, got {len(inputs)}")
        if self._lattice_plan is not None:
            crisp = self._evaluate_two_input_lattice(inputs)
            if crisp is not None:
                return crisp
        if self._single_input_plan is not None:
            crisp = []
            for table, x in zip(self._single_input_plan, inputs, strict=True):
                values = table.evaluate(x[0]) if len(x) == 1 else None
                if values is None:
                    break
                crisp += values
            else:
                return crisp
        strengths = [0.0] * self._n_slots
        for k, (system, targets) in enumerate(self._pairs):
            system.accumulate_strengths(inputs[k], strengths, targets)
        np.minimum(np.array(strengths).reshape(self._shape), self._samples, out=self._clipped)
        np.maximum.reduce(self._clipped, axis=0, out=self._aggregated)
        return [
            moment / area if area > 0.0 else ZERO_AREA_FALLBACK
            for area, moment in np.dot(self._aggregated, self._weights).tolist()
        ]
