"""SPEC section 5 indices accumulated block by block, as ``smm_analysis.metrics`` computes them on arrays.

Which indices, of which signal and by which reduction: ``smm_analysis.metrics.METRICS``; each
:class:`~smm_analysis.metrics.Reduction` has its streaming state here. Terms are the in-memory functions'
float operations; only the summation order differs (pairwise within a block, blocks in step order). Maxima
and counts are exact; the sums' tolerance: docs/BAGS.md, "Streaming analysis".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from smm_analysis.errors import MetricsInputError
from smm_analysis.metrics import (
    CARTESIAN_AXES,
    AxisError,
    Group,
    JointIndices,
    Metric,
    Reduction,
    Signal,
    StepMetrics,
    metrics_of,
)
from smm_analysis.runs.stream import JOINTS, StepBlock
from smm_dynamics import SMMParameters, end_effector_position

__all__ = ["SUM_RELATIVE_TOLERANCE", "IndexAccumulator", "StreamIndices"]

FloatArray = NDArray[np.float64]
_NS_PER_S = 1e9
_MM_PER_M = 1e3
SUM_RELATIVE_TOLERANCE = 1e-12
"""Stated bound of |streamed - in-memory| / |in-memory| for the summed indices (docs/BAGS.md)."""


def _finite(name: str, values: FloatArray, first_step: int) -> None:
    if not np.all(np.isfinite(values)):
        bad = int(np.argmin(np.all(np.isfinite(values.reshape(values.shape[0], -1)), axis=1)))
        raise MetricsInputError(f"{name} holds NaN or Inf at step {first_step + bad}")


class _Trapezoid:
    """Integral of each column over time, trapezoidal, carried across blocks."""

    def __init__(self, width: int) -> None:
        self.total = np.zeros(width)
        self._last: tuple[float, FloatArray] | None = None

    def add(self, t_s: FloatArray, values: FloatArray) -> None:
        if self._last is not None:
            t_s = np.concatenate([[self._last[0]], t_s])
            values = np.vstack([self._last[1], values])
        self._last = (float(t_s[-1]), values[-1].copy())
        if t_s.size < 2:
            return
        # One contiguous row per column: numpy's pairwise sum, as the 1-D in-memory sum.
        terms = np.ascontiguousarray((0.5 * (values[1:] + values[:-1]) * np.diff(t_s)[:, None]).T)
        self.total += np.array([float(np.sum(row)) for row in terms])


class _Running:
    """Max of |x|, sum of |x| and count of each column."""

    def __init__(self, width: int) -> None:
        self.maximum = np.zeros(width)
        self.total = np.zeros(width)
        self.count = 0

    def add(self, values: FloatArray) -> None:
        magnitude = np.abs(values)
        self.maximum = np.maximum(self.maximum, magnitude.max(axis=0))
        self.total += np.array([float(np.sum(row)) for row in np.ascontiguousarray(magnitude.T)])
        self.count += values.shape[0]


class _Reducer:
    """The streaming state of one :class:`~smm_analysis.metrics.Reduction` over each column of a signal."""

    def __init__(self, reduction: Reduction, width: int) -> None:
        self.reduction = reduction
        self.running = _Running(width)
        self.trapezoid = _Trapezoid(width)
        self.increments = np.zeros(width)
        self.last: FloatArray | None = None

    def add(self, t_s: FloatArray, values: FloatArray) -> None:
        if self.reduction in (Reduction.MAX_ABS, Reduction.MEAN_ABS):
            self.running.add(values)
        elif self.reduction in (Reduction.RMS_OVER_TIME, Reduction.INTEGRAL_SQUARE):
            self.trapezoid.add(t_s, values**2)
        elif self.reduction is Reduction.INCREMENT_RMS:
            joined = values if self.last is None else np.vstack([self.last, values])
            squared = np.ascontiguousarray((np.diff(joined, axis=0) ** 2).T)
            self.increments += np.array([float(np.sum(row)) for row in squared])
            self.last = values[-1:].copy()

    def value(self, column: int, steps: int, t_f: float) -> float:
        if self.reduction is Reduction.MAX_ABS:
            return float(self.running.maximum[column])
        if self.reduction is Reduction.MEAN_ABS:
            return float(self.running.total[column] / self.running.count)
        if self.reduction is Reduction.RMS_OVER_TIME:
            return math.sqrt(float(self.trapezoid.total[column]) / t_f)
        if self.reduction is Reduction.INTEGRAL_SQUARE:
            return float(self.trapezoid.total[column])
        return math.sqrt(float(self.increments[column]) / (steps - 1))


class _StepResponse:
    """:func:`smm_analysis.metrics.step_metrics` of one joint, streamed (step at the first stamp)."""

    def __init__(self, target: float, initial: float, band: float = 0.02) -> None:
        self.target, self.initial, self.band = target, initial, band
        self.amplitude = target - initial
        self.crossings: dict[float, float] = {}
        self.peak = -math.inf
        self.previous: tuple[float, float] | None = None
        self.outside: tuple[float, float] | None = None
        self.after_outside: tuple[float, float] | None = None
        self.first_t: float | None = None

    def add(self, t_s: FloatArray, output: FloatArray) -> None:
        normalised = (output - self.initial) / self.amplitude
        if self.first_t is None:
            self.first_t = float(t_s[0])
        for level in (0.1, 0.9):
            if level in self.crossings:
                continue
            reached = np.nonzero(normalised >= level)[0]
            if reached.size == 0:
                continue
            index = int(reached[0])
            if index == 0 and self.previous is None:
                self.crossings[level] = float(t_s[0])
                continue
            if index == 0:
                assert self.previous is not None
                before_t, before = self.previous
            else:
                before_t, before = float(t_s[index - 1]), float(normalised[index - 1])
            fraction = (level - before) / (normalised[index] - before)
            self.crossings[level] = float(before_t + fraction * (t_s[index] - before_t))
        self.peak = max(self.peak, float(np.max(normalised)))
        distance = np.abs(normalised - 1.0)
        if self.outside is not None and self.after_outside is None:
            self.after_outside = (float(t_s[0]), float(distance[0]))
        outside = np.nonzero(distance > self.band)[0]
        if outside.size:
            last = int(outside[-1])
            self.outside = (float(t_s[last]), float(distance[last]))
            self.after_outside = (
                (float(t_s[last + 1]), float(distance[last + 1])) if last + 1 < normalised.size else None
            )
        self.previous = (float(t_s[-1]), float(normalised[-1]))

    def result(self) -> StepMetrics:
        rise_start = self.crossings.get(0.1, math.inf)
        rise_end = self.crossings.get(0.9, math.inf)
        rise_time = rise_end - rise_start if math.isfinite(rise_end) else math.inf
        overshoot_fraction = max(0.0, self.peak - 1.0)
        if self.outside is None:
            assert self.first_t is not None
            settling = self.first_t
        elif self.after_outside is None:
            settling = math.inf
        else:
            (t0, d0), (t1, d1) = self.outside, self.after_outside
            fraction = (d0 - self.band) / (d0 - d1)
            settling = float(t0 + fraction * (t1 - t0))
        return StepMetrics(
            rise_time=rise_time,
            overshoot=overshoot_fraction * abs(self.amplitude),
            overshoot_fraction=overshoot_fraction,
            settling_time=settling,
        )


@dataclass(frozen=True)
class StreamIndices:
    """The indices of a streamed run (as :func:`smm_analysis.runs.indices.evaluate` gives them)."""

    joints: Mapping[str, JointIndices]
    end_effector: Mapping[str, AxisError]
    step: Mapping[str, StepMetrics] | None
    steps: int
    first_ns: int
    last_ns: int


class IndexAccumulator:
    """Eq. 42-45, end-effector errors and step metrics of a run fed block by block in step order."""

    def __init__(self, params: SMMParameters | None = None) -> None:
        self.params = params if params is not None else SMMParameters()
        self.t0: int | None = None
        self.last_ns = 0
        self.steps = 0
        self.reducers: dict[str, _Reducer] = {
            _key(metric): _Reducer(metric.reduction, 3 if metric.group is Group.END_EFFECTOR else 2)
            for metric in (*metrics_of(Group.JOINT), *metrics_of(Group.END_EFFECTOR))
        }
        self.is_step = True
        self.first_reference: FloatArray | None = None
        self.first_position: FloatArray | None = None
        self.responses: list[_StepResponse | None] | None = None

    def add(self, block: StepBlock) -> None:
        """Adds the block's steps (the next ones of the run)."""
        n = block.t_ns.size
        if n == 0:
            return
        for name, values in (
            ("reference", block.desired_position),
            ("position", block.position),
            ("torque", block.command_torque),
        ):
            _finite(name, values, block.first_step)
        if self.t0 is None:
            self.t0 = int(block.t_ns[0])
        t_s = (block.t_ns - self.t0).astype(np.float64) / _NS_PER_S
        self.last_ns = int(block.t_ns[-1])
        self.steps += n
        desired, position = block.desired_position, block.position
        desired_xyz = np.asarray(end_effector_position(desired, self.params), dtype=np.float64)
        actual_xyz = np.asarray(end_effector_position(position, self.params), dtype=np.float64)
        signals = {
            Signal.TRACKING_ERROR: desired - position,
            Signal.TORQUE: block.command_torque,
            Signal.END_EFFECTOR_ERROR: (desired_xyz - actual_xyz) * _MM_PER_M,
        }
        for metric in (*metrics_of(Group.JOINT), *metrics_of(Group.END_EFFECTOR)):
            self.reducers[_key(metric)].add(t_s, signals[metric.signal])
        self._add_step(block, t_s)

    def _add_step(self, block: StepBlock, t_s: FloatArray) -> None:
        if not self.is_step:
            return
        desired = block.desired_position
        if self.first_reference is None:
            self.first_reference = desired[0].copy()
            self.first_position = block.position[0].copy()
            if np.all(self.first_reference == self.first_position):
                self.is_step = False  # a constant reference at the start position is a hold, not a step
                return
            self.responses = [
                _StepResponse(float(self.first_reference[j]), float(self.first_position[j]))
                if self.first_reference[j] != self.first_position[j]
                else None
                for j in range(2)
            ]
        if np.any(block.reference[:, 1:, :] != 0.0) or np.any(desired != self.first_reference):
            self.is_step = False
            return
        assert self.responses is not None
        for j, response in enumerate(self.responses):
            if response is not None:
                response.add(t_s, block.position[:, j])

    def result(self) -> StreamIndices:
        """The indices.

        Raises:
            MetricsInputError: Fewer than 2 steps.
        """
        if self.steps < 2 or self.t0 is None:
            raise MetricsInputError(f"t_ns needs at least 2 samples, got {self.steps}")
        t_f = float(np.float64(self.last_ns - self.t0) / _NS_PER_S)
        joints = {
            joint: JointIndices(
                **{m.name: self.reducers[_key(m)].value(j, self.steps, t_f) for m in metrics_of(Group.JOINT)}
            )
            for j, joint in enumerate(JOINTS)
        }
        cartesian = {
            axis: AxisError(
                **{
                    m.name: self.reducers[_key(m)].value(i, self.steps, t_f)
                    for m in metrics_of(Group.END_EFFECTOR)
                }
            )
            for i, axis in enumerate(CARTESIAN_AXES)
        }
        step = None
        if self.is_step and self.responses is not None:
            step = {
                joint: response.result()
                for joint, response in zip(JOINTS, self.responses, strict=True)
                if response is not None
            }
        return StreamIndices(
            joints=joints,
            end_effector=cartesian,
            step=step,
            steps=self.steps,
            first_ns=self.t0,
            last_ns=self.last_ns,
        )


def _key(metric: Metric) -> str:
    return f"{metric.group.value}:{metric.name}"
