"""Exact centroid tables: the defuzzified outputs of the common cases without array operations.

:class:`SingleInputCentroids` (one Gaussian input) and :class:`LabelPairCentroids` (one clipped output
label, or two whose levels add up to 1) equal the sums over the grid of :mod:`fuzzy` up to rounding.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left, bisect_right
from collections.abc import Sequence
from itertools import combinations
from math import exp

import numpy as np
import numpy.typing as npt

from smm_controller.fuzzy import ZERO_AREA_FALLBACK

__all__ = ["LabelPairCentroids", "SingleInputCentroids"]

FloatArray = npt.NDArray[np.float64]

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
