"""Batched Mamdani evaluation: several rule bases, all outputs, in one pass per control step.

:class:`MamdaniBatch` gives the outputs of :mod:`fuzzy`'s definition, taking the fast paths of
:mod:`fuzzy_tables` where they apply (docs/DESIGN.md, "The fuzzy engine").
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from smm_controller.fuzzy import ZERO_AREA_FALLBACK, Lattice, MamdaniSystem, centroid_weights
from smm_controller.fuzzy_tables import LabelPairCentroids, SingleInputCentroids

__all__ = ["MamdaniBatch", "evaluate_system"]

FloatArray = npt.NDArray[np.float64]

# Two rules of a uniform triangular partition with the other input on a peak have strengths adding up
# to 1 up to rounding; LabelPairCentroids assumes that sum.
_UNIT_SUM_TOLERANCE = 1e-9


@lru_cache(maxsize=16)
def _label_pair_centroids(samples: bytes, labels: int, weights: bytes) -> LabelPairCentroids:
    """The tables of one output MF family and grid, built once per process."""
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
    """The table of one rule base and grid, built once per process."""
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
    ) -> tuple[tuple[Lattice, Lattice, int, list[tuple[int, ...]], list[tuple[int, ...]]], ...] | None:
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
        dense evaluation), and the cases are told apart by which of the four degrees are positive, with
        no list of the fired rules: this runs every control step.
        """
        assert self._lattice_plan is not None
        n_outputs = self._n_outputs
        pair_centroids = self._pair_centroids
        crisp = [0.0] * self._n_rows
        # The systems whose four rules fire, and per rule its strength slots (one per output) and level.
        four_rules: list[int] = []
        slots: list[int] = []
        levels: list[float] = []
        for system_index, (plan, x) in enumerate(zip(self._lattice_plan, inputs, strict=True)):
            if len(x) != 2:
                return None
            x0, x1 = x
            first, second, radix, targets, labels = plan
            low, high, spacing, last, sides = first
            low1, high1, spacing1, last1, sides1 = second
            if not (low <= x0 <= high and low1 <= x1 <= high1):
                return None
            i = int((x0 - low) // spacing)
            if i > last:  # noqa: PLR1730 (faster than min() here)
                i = last
            peak_left, falling_width, foot_right, rising_width = sides[i]
            degree_i = (peak_left - x0) / falling_width
            degree_i1 = (x0 - foot_right) / rising_width
            j = int((x1 - low1) // spacing1)
            if j > last1:  # noqa: PLR1730 (faster than min() here)
                j = last1
            peak_left, falling_width, foot_right, rising_width = sides1[j]
            degree_j = (peak_left - x1) / falling_width
            degree_j1 = (x1 - foot_right) / rising_width
            # Clamp at 1 as lattice_pair does; a degree <= 0 fires no rule. AND = min.
            degree_i = 1.0 if degree_i > 1.0 else degree_i
            degree_i1 = 1.0 if degree_i1 > 1.0 else degree_i1
            degree_j = 1.0 if degree_j > 1.0 else degree_j
            degree_j1 = 1.0 if degree_j1 > 1.0 else degree_j1
            cell = i * radix + j
            both_i = degree_i > 0.0 and degree_i1 > 0.0
            both_j = degree_j > 0.0 and degree_j1 > 0.0
            if both_i and both_j:
                four_rules.append(system_index)
                slots += targets[cell]
                slots += targets[cell + 1]
                slots += targets[cell + radix]
                slots += targets[cell + radix + 1]
                levels += (
                    degree_i if degree_i < degree_j else degree_j,
                    degree_i if degree_i < degree_j1 else degree_j1,
                    degree_i1 if degree_i1 < degree_j else degree_j,
                    degree_i1 if degree_i1 < degree_j1 else degree_j1,
                )
                continue
            # The one (or first) label of each input that fires, as a cell offset and a degree.
            if degree_i > 0.0:
                di = degree_i
            elif degree_i1 > 0.0:
                di, cell = degree_i1, cell + radix
            else:
                return None
            if degree_j > 0.0:
                dj = degree_j
            elif degree_j1 > 0.0:
                dj, cell = degree_j1, cell + 1
            else:
                return None
            level = di if di < dj else dj
            row = system_index * n_outputs
            rule = labels[cell]
            if not (both_i or both_j):
                for o in range(n_outputs):
                    crisp[row + o] = pair_centroids[o].single(rule[o], level)
                continue
            # Two rules, in the order of the cells: (i, j) and (i + 1, j), or (i, j) and (i, j + 1).
            if both_i:
                other_cell, other_level = cell + radix, (degree_i1 if degree_i1 < dj else dj)
            else:
                other_cell, other_level = cell + 1, (di if di < degree_j1 else degree_j1)
            if abs(level + other_level - 1.0) > _UNIT_SUM_TOLERANCE:
                return None  # two whose sum is not 1: impossible on a partition of unity
            other_rule = labels[other_cell]
            for o in range(n_outputs):
                label, other_label = rule[o], other_rule[o]
                if label == other_label:
                    crisp[row + o] = pair_centroids[o].single(label, max(level, other_level))
                else:
                    crisp[row + o] = pair_centroids[o].pair(label, level, other_label, other_level)
        if four_rules:
            self._clip_and_defuzzify(four_rules, slots, levels, crisp)
        return crisp

    def _clip_and_defuzzify(
        self, systems: list[int], slots: list[int], levels: list[float], crisp: list[float]
    ) -> None:
        """Numpy min/max/centroid of the given systems' four fired rules each (their slots and levels)."""
        firing, firing_view, gathered, gathered_view, aggregated, aggregated_view = self._lattice_buffers[
            len(systems) - 1
        ]
        firing[:] = levels
        self._sample_table.take(slots, 0, gathered, "clip")
        np.minimum(gathered_view, firing_view, out=gathered_view)
        np.maximum.reduce(gathered_view, axis=1, out=aggregated_view)
        values = np.dot(aggregated, self._weights).tolist()
        n_outputs = self._n_outputs
        for k, system_index in enumerate(systems):
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


def evaluate_system(system: MamdaniSystem, x: Sequence[float]) -> tuple[float, ...]:
    """Crisp outputs of one system for one crisp input vector, as the control step evaluates them."""
    return tuple(MamdaniBatch([system]).evaluate([x])[0])
