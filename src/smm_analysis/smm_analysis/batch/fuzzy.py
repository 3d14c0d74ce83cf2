"""The fuzzy systems of the chain for N runs at once: exact centroids without a grid per evaluation.

Row-wise (a run's outputs do not depend on the other rows); equal to the scalar engine's dense evaluation
up to rounding. The layer-cake method: docs/SWEEPS.md, "The batched fuzzy engine".
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from smm_controller.fuzzy import MamdaniSystem, centroid_weights
from smm_controller.fuzzy_batch import MamdaniBatch
from smm_controller.rules import TABLE_1, TABLE_7, fleso_bandwidth_system, pd_gain_system

__all__ = ["BandwidthFuzzy", "LabelSetCentroids", "PDGainFuzzy"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_KEY_SHIFT = 2.0
"""Memberships lie in [0, 1]; the table of label set r is shifted by 2 (r + 1) so that one sorted key
array holds every set's samples."""


class LabelSetCentroids:
    """Area and moment of max-of-clipped output labels from per-label-set tables (see module docstring).

    Args:
        samples: Output MF samples, shape (n_labels, grid) (n_labels <= 10).
        weights: ``centroid_weights(grid)``, shape (grid, 2).
    """

    def __init__(self, samples: FloatArray, weights: FloatArray) -> None:
        n_labels, grid = samples.shape
        masks = np.arange(1, 2**n_labels)
        keys = np.empty((masks.size, grid))
        below = np.zeros((masks.size, grid + 1, 2))
        above = np.zeros((masks.size, grid + 1, 2))
        for row, mask in enumerate(masks):
            members = [label for label in range(n_labels) if mask >> label & 1]
            envelope = samples[members].max(axis=0)
            order = np.argsort(envelope, kind="stable")
            values = envelope[order]
            w = weights[order]
            keys[row] = values + _KEY_SHIFT * (row + 1)
            below[row, 1:] = np.cumsum(w * values[:, None], axis=0)
            above[row, :-1] = np.cumsum(w[::-1], axis=0)[::-1]
        self._grid = grid
        self._keys = keys.ravel()
        self._below_area, self._below_moment = (np.ascontiguousarray(below[..., k].ravel()) for k in range(2))
        self._above_area, self._above_moment = (np.ascontiguousarray(above[..., k].ravel()) for k in range(2))

    def _clipped(self, mask: IntArray, level: FloatArray) -> tuple[FloatArray, FloatArray]:
        """F_K(level) for label sets ``mask`` (bit l = label l): (area, moment), each like ``level``."""
        row = mask - 1
        found = np.searchsorted(self._keys, level + _KEY_SHIFT * mask, side="right")
        index = found + row  # row r's table has grid + 1 entries, its keys grid
        area = np.take(self._below_area, index) + level * np.take(self._above_area, index)
        moment = np.take(self._below_moment, index) + level * np.take(self._above_moment, index)
        return area, moment

    def centroid(self, labels: IntArray, levels: FloatArray, order: IntArray | None = None) -> FloatArray:
        """Centroid of ``max_r min(levels[..., r], S[labels[..., r]])``, shape levels.shape[:-1].

        Args:
            labels: Output label of each rule, shape (..., m).
            levels: Firing strength of each rule, >= 0, shape (..., m); at least one > 0 per row.
            order: ``argsort(-levels, axis=-1, kind="stable")`` if already known.
        """
        if order is None:
            order = np.argsort(-levels, axis=-1, kind="stable")
        upper = np.take_along_axis(levels, order, axis=-1)
        sorted_labels = np.take_along_axis(labels, order, axis=-1)
        masks = np.bitwise_or.accumulate(np.left_shift(1, sorted_labels), axis=-1)
        # F_K(0) = 0: the last layer has no lower term.
        area, moment = self._clipped(masks, upper)
        lower_area, lower_moment = self._clipped(masks[..., :-1], upper[..., 1:])
        area[..., :-1] -= lower_area
        moment[..., :-1] -= lower_moment
        total_area = area.sum(axis=-1)
        total_moment = moment.sum(axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            crisp: FloatArray = np.where(total_area > 0.0, total_moment / total_area, 0.0)
        return crisp


def _output_tables(system: MamdaniSystem) -> list[LabelSetCentroids]:
    weights = centroid_weights(system.grid)
    return [
        LabelSetCentroids(np.ascontiguousarray(system.output_samples[:, o, :]), weights)
        for o in range(len(system.outputs))
    ]


def _rule_labels(system: MamdaniSystem) -> IntArray:
    """Per flattened antecedent cell, the output label of each output, shape (cells, outputs)."""
    n_outputs, n_labels = len(system.outputs), system.n_labels
    table = [
        [slot - o * n_labels for o, slot in enumerate(slots)]
        for slots in system.slot_table(range(n_outputs * n_labels))
    ]
    return np.array(table, dtype=np.int64)


class _Lattice:
    """A uniform triangular partition on arrays: ``FuzzyVariable.lattice_pair`` element-wise."""

    def __init__(self, data: Any) -> None:
        low, high, spacing, last, sides = data
        self.low, self.high, self.spacing, self.last = low, high, spacing, last
        table = np.array(sides, dtype=np.float64)
        self.peak_left, self.falling, self.foot_right, self.rising = table.T

    def pair(self, x: FloatArray) -> tuple[IntArray, FloatArray, FloatArray]:
        """(k, degree of label k, degree of label k + 1) at x in [low, high], clamped to [0, 1]."""
        k = np.minimum(np.floor_divide(x - self.low, self.spacing).astype(np.int64), self.last)
        left = np.minimum((self.peak_left[k] - x) / self.falling[k], 1.0)
        right = np.minimum((x - self.foot_right[k]) / self.rising[k], 1.0)
        return k, np.maximum(left, 0.0), np.maximum(right, 0.0)


class PDGainFuzzy:
    """The fuzzy PD gain schedule's inference (Tables 1 and 7) for arrays of (e~, ce~) per joint.

    Args:
        grid_points: Defuzzification grid size.
    """

    def __init__(self, grid_points: int) -> None:
        systems = [pd_gain_system(table, grid_points) for table in (TABLE_1, TABLE_7)]
        self._lattices = [
            (_Lattice(system.inputs[0]._lattice_data()), _Lattice(system.inputs[1]._lattice_data()))
            for system in systems
        ]
        self._radix = [len(system.inputs[1].labels) for system in systems]
        self._labels = [_rule_labels(system) for system in systems]
        samples = systems[0].output_samples
        if any(
            not np.array_equal(system.output_samples, samples) for system in systems
        ) or not np.array_equal(samples[:, 0, :], samples[:, 1, :]):
            raise ValueError("the PD rule bases must share one output MF family")
        self._table = _output_tables(systems[0])[0]

    def evaluate(self, x: FloatArray, c: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(f(k_e), f(k_de)) for normalised inputs x = e~, c = ce~ in [-1, 1], each shape (N, 2)."""
        labels = []
        levels = []
        for joint in range(2):
            first, second = self._lattices[joint]
            i, di, di1 = first.pair(x[:, joint])
            j, dj, dj1 = second.pair(c[:, joint])
            radix = self._radix[joint]
            cell = i * radix + j
            cells = np.stack((cell, cell + 1, cell + radix, cell + radix + 1), axis=-1)
            level = np.stack(
                (np.minimum(di, dj), np.minimum(di, dj1), np.minimum(di1, dj), np.minimum(di1, dj1)), axis=-1
            )
            label = self._labels[joint][cells]
            labels += [label[..., 0], label[..., 1]]
            levels += [level, level]
        # Both outputs have the same MFs: one table, all four (joint, output) pairs at once; the two
        # outputs of a joint share their levels, so one sort serves both.
        stacked = np.stack(levels)
        order = np.argsort(-stacked[::2], axis=-1, kind="stable").repeat(2, axis=0)
        crisp = self._table.centroid(np.stack(labels), stacked, order)
        return np.stack((crisp[0], crisp[2]), axis=-1), np.stack((crisp[1], crisp[3]), axis=-1)


class BandwidthFuzzy:
    """The FLESO bandwidth rule base (one Gaussian input, Section III.C) for arrays of s per joint.

    The scalar engine's own piecewise tables (``SingleInputCentroids``: per interval between breakpoints of
    the input, a constant plus a coefficient per input label) evaluated on arrays: one search for the
    interval, the same sums in the same order.

    Args:
        grid_points: Defuzzification grid size.
    """

    def __init__(self, grid_points: int) -> None:
        plan = MamdaniBatch([fleso_bandwidth_system(grid_points)])._single_input_plan
        if plan is None:
            raise ValueError("the FLESO bandwidth rule base has no single-input tables")
        table = plan[0]
        self._means = np.array([mean for mean, _ in table.gaussians])
        self._widths = np.array([width for _, width in table.gaussians])
        self._breakpoints = np.array(table.breakpoints)
        intervals = table._coefficients
        n_inputs = len(table.gaussians)
        self._constant = np.array([[interval[0][0], interval[0][1]] for interval in intervals])
        self._area = np.zeros((len(intervals), n_inputs))
        self._moment = np.zeros((len(intervals), n_inputs))
        for k, interval in enumerate(intervals):
            for a, area, moment in interval[0][2]:
                self._area[k, a] = area
                self._moment[k, a] = moment

    def evaluate(self, s: FloatArray) -> FloatArray:
        """f(w) for s in [-1, 1], any shape."""
        interval = np.searchsorted(self._breakpoints, s, side="right")
        memberships = np.exp(-((s[..., None] - self._means) ** 2) / self._widths)
        area = self._constant[interval, 0]
        moment = self._constant[interval, 1]
        coefficients_area = self._area[interval]
        coefficients_moment = self._moment[interval]
        for a in range(self._means.size):
            area = area + memberships[..., a] * coefficients_area[..., a]
            moment = moment + memberships[..., a] * coefficients_moment[..., a]
        with np.errstate(divide="ignore", invalid="ignore"):
            crisp: FloatArray = np.where(area > 0.0, moment / area, 0.0)
        return crisp
