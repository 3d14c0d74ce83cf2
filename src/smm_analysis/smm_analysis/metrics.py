"""Performance indices (SPEC section 5, paper eq. 42-45), step metrics, end-effector errors, and their table.

Arrays in, floats out, shared by the offline loop and the bag analysis; stamps are integer ns, strictly
increasing. :data:`METRICS` names every metric once (name, unit, reduction, whether the batched loop
computes it); everything that lists metrics reads it. Definitions: docs/METRICS.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import ArrayLike, NDArray

from smm_analysis.errors import MetricsInputError
from smm_dynamics import SMMParameters, end_effector_position

__all__ = [
    "CARTESIAN_AXES",
    "METRICS",
    "AxisError",
    "Group",
    "JointIndices",
    "Metric",
    "Reduction",
    "Signal",
    "StepMetrics",
    "control_energy",
    "end_effector_errors",
    "joint_indices",
    "max_abs_error",
    "mean_abs_error",
    "metric",
    "metrics_of",
    "rms_error",
    "step_metrics",
    "torque_increment_rms",
    "validated_time",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

CARTESIAN_AXES: tuple[str, str, str] = ("x", "y", "z")
_NS_PER_S = 1e9
_MM_PER_M = 1e3


@dataclass(frozen=True)
class JointIndices:
    """Indices of eq. 42-45 for one joint.

    Attributes:
        Ma: Maximal absolute tracking error (rad), eq. 42.
        Ave: Mean absolute tracking error over the samples (rad), eq. 43.
        RMS: Root mean square tracking error sqrt((1/t_f) integral e^2 dt) (rad), eq. 44.
        eps_u: Control energy integral tau^2 dt (N^2 m^2 s), eq. 45.
        du_rms: Torque smoothness, RMS torque increment per step (N m); see :func:`torque_increment_rms`.
    """

    Ma: float
    Ave: float
    RMS: float
    eps_u: float
    du_rms: float


@dataclass(frozen=True)
class StepMetrics:
    """Step-response metrics of one joint (see the module docstring for the definitions).

    Attributes:
        rise_time: 10-90 % rise time (s).
        overshoot: Overshoot beyond the target (rad), >= 0.
        overshoot_fraction: Overshoot divided by the step size (dimensionless; x100 = percent).
        settling_time: 2 % settling time from the step (s).
    """

    rise_time: float
    overshoot: float
    overshoot_fraction: float
    settling_time: float


@dataclass(frozen=True)
class AxisError:
    """End-effector position error along one Cartesian axis.

    Attributes:
        max_mm: Maximal absolute error (mm).
        rms_mm: RMS error over time (mm), same integration as :func:`rms_error`.
    """

    max_mm: float
    rms_mm: float


def validated_time(t_ns: ArrayLike, *, name: str = "t_ns") -> IntArray:
    """Checks a stamp array: 1-D integers (ns), at least two samples, strictly increasing.

    Args:
        t_ns: Stamps (ns), shape (N,).
        name: Name used in error messages.

    Returns:
        The stamps as int64, shape (N,).

    Raises:
        MetricsInputError: Wrong dtype or shape, fewer than 2 samples, or not strictly increasing.
    """
    stamps = np.asarray(t_ns)
    if stamps.ndim != 1:
        raise MetricsInputError(f"{name} must be 1-D, got shape {stamps.shape}")
    if not np.issubdtype(stamps.dtype, np.integer):
        raise MetricsInputError(f"{name} must hold integer nanoseconds, got dtype {stamps.dtype}")
    if stamps.size < 2:
        raise MetricsInputError(f"{name} needs at least 2 samples, got {stamps.size}")
    stamps = stamps.astype(np.int64)
    steps = np.diff(stamps)
    if np.any(steps <= 0):
        bad = int(np.argmax(steps <= 0))
        raise MetricsInputError(
            f"{name} must be strictly increasing, got {int(stamps[bad])} then {int(stamps[bad + 1])} "
            f"at index {bad}"
        )
    return stamps


def _validated_series(name: str, values: ArrayLike, length: int | None = None) -> FloatArray:
    series = np.asarray(values, dtype=np.float64)
    if series.ndim != 1:
        raise MetricsInputError(f"{name} must be 1-D, got shape {series.shape}")
    if series.size == 0:
        raise MetricsInputError(f"{name} must not be empty")
    if length is not None and series.size != length:
        raise MetricsInputError(f"{name} has {series.size} samples but the time base has {length}")
    if not np.all(np.isfinite(series)):
        raise MetricsInputError(f"{name} holds NaN or Inf at index {int(np.argmin(np.isfinite(series)))}")
    return series


def _validated_joint_array(name: str, values: ArrayLike, length: int) -> FloatArray:
    array = np.asarray(values, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 2:
        raise MetricsInputError(f"{name} must have shape (N, 2), got {array.shape}")
    if array.shape[0] != length:
        raise MetricsInputError(f"{name} has {array.shape[0]} samples but the time base has {length}")
    if not np.all(np.isfinite(array)):
        raise MetricsInputError(f"{name} holds NaN or Inf")
    return array


def _integral(t_s: FloatArray, values: FloatArray) -> float:
    return float(np.sum(0.5 * (values[1:] + values[:-1]) * np.diff(t_s)))


def _seconds(stamps: IntArray) -> FloatArray:
    """Seconds relative to the first stamp, exact in integer arithmetic before the conversion."""
    seconds: FloatArray = (stamps - stamps[0]).astype(np.float64) / _NS_PER_S
    return seconds


def max_abs_error(error: ArrayLike) -> float:
    """Eq. 42: max |e| (same unit as ``error``), ``error`` shape (N,)."""
    return float(np.max(np.abs(_validated_series("error", error))))


def mean_abs_error(error: ArrayLike) -> float:
    """Eq. 43: (1/n) sum |e(i)| (same unit as ``error``), ``error`` shape (N,)."""
    return float(np.mean(np.abs(_validated_series("error", error))))


def rms_error(t_ns: ArrayLike, error: ArrayLike) -> float:
    """Eq. 44: sqrt((1/t_f) integral e^2 dt), trapezoidal over the stamps.

    Args:
        t_ns: Stamps (ns), shape (N,).
        error: Tracking error at the stamps, shape (N,).

    Returns:
        RMS error (same unit as ``error``).
    """
    stamps = validated_time(t_ns)
    series = _validated_series("error", error, stamps.size)
    t_s = _seconds(stamps)
    return math.sqrt(_integral(t_s, series**2) / t_s[-1])


def control_energy(t_ns: ArrayLike, torque: ArrayLike) -> float:
    """Eq. 45: integral tau^2 dt, trapezoidal over the stamps.

    Args:
        t_ns: Stamps (ns), shape (N,).
        torque: Control torque at the stamps (N m), shape (N,).

    Returns:
        Control energy (N^2 m^2 s).
    """
    stamps = validated_time(t_ns)
    series = _validated_series("torque", torque, stamps.size)
    return _integral(_seconds(stamps), series**2)


def torque_increment_rms(torque: ArrayLike) -> float:
    """Torque smoothness: sqrt(mean((tau[k+1] - tau[k])^2)) (N m per step), ``torque`` shape (N,), N >= 2."""
    series = _validated_series("torque", torque)
    if series.size < 2:
        raise MetricsInputError(f"torque needs at least 2 samples for an increment, got {series.size}")
    return math.sqrt(float(np.mean(np.diff(series) ** 2)))


def joint_indices(
    t_ns: ArrayLike, reference: ArrayLike, position: ArrayLike, torque: ArrayLike
) -> dict[str, JointIndices]:
    """Eq. 42-45 for both joints.

    Args:
        t_ns: Stamps (ns), shape (N,).
        reference: Desired position q_d (rad), shape (N, 2).
        position: Position the error is measured on (true plant position where recorded) (rad),
            shape (N, 2).
        torque: Control torque (N m), shape (N, 2).

    Returns:
        ``{"alpha": JointIndices, "beta": JointIndices}``.
    """
    stamps = validated_time(t_ns)
    desired = _validated_joint_array("reference", reference, stamps.size)
    actual = _validated_joint_array("position", position, stamps.size)
    effort = _validated_joint_array("torque", torque, stamps.size)
    signals = {Signal.TRACKING_ERROR: desired - actual, Signal.TORQUE: effort}
    return {
        name: JointIndices(
            **{row.name: row.of(stamps, signals[row.signal][:, joint]) for row in metrics_of(Group.JOINT)}
        )
        for joint, name in enumerate(("alpha", "beta"))
    }


def _first_crossing(t_s: FloatArray, normalised: FloatArray, level: float) -> float:
    """Time at which ``normalised`` first reaches ``level`` (linear interpolation), inf if never."""
    reached = np.nonzero(normalised >= level)[0]
    if reached.size == 0:
        return math.inf
    index = int(reached[0])
    if index == 0:
        return float(t_s[0])
    before, after = normalised[index - 1], normalised[index]
    fraction = (level - before) / (after - before)
    return float(t_s[index - 1] + fraction * (t_s[index] - t_s[index - 1]))


def step_metrics(
    t_ns: ArrayLike,
    response: ArrayLike,
    target: float,
    *,
    initial: float = 0.0,
    step_time_ns: int | None = None,
    settling_band: float = 0.02,
) -> StepMetrics:
    """Rise time (10-90 %), overshoot and settling time of a step response.

    Args:
        t_ns: Stamps (ns), shape (N,).
        response: Output (rad), shape (N,).
        target: Final value commanded by the step (rad).
        initial: Output value before the step (rad); ``target != initial``.
        step_time_ns: Stamp of the step (ns); default the first stamp. Earlier samples are ignored.
        settling_band: Half-width of the settling band as a fraction of the step size, in (0, 1).

    Returns:
        The metrics; times are relative to the step (s).

    Raises:
        MetricsInputError: Malformed arrays, a zero step, a bad band or a step after the last sample.
    """
    stamps = validated_time(t_ns)
    output = _validated_series("response", response, stamps.size)
    if not (math.isfinite(target) and math.isfinite(initial)):
        raise MetricsInputError(f"target and initial must be finite, got {target!r}, {initial!r}")
    amplitude = target - initial
    if amplitude == 0.0:
        raise MetricsInputError(f"target must differ from initial, both are {target!r}")
    if not 0.0 < settling_band < 1.0:
        raise MetricsInputError(f"settling_band must be in (0, 1), got {settling_band!r}")
    start_ns = int(stamps[0]) if step_time_ns is None else int(step_time_ns)
    keep = stamps >= start_ns
    if np.count_nonzero(keep) < 2:
        raise MetricsInputError(f"step_time_ns {start_ns} leaves fewer than 2 samples")
    t_s = (stamps[keep] - start_ns).astype(np.float64) / _NS_PER_S
    normalised = (output[keep] - initial) / amplitude

    rise_start = _first_crossing(t_s, normalised, 0.1)
    rise_end = _first_crossing(t_s, normalised, 0.9)
    rise_time = rise_end - rise_start if math.isfinite(rise_end) else math.inf

    overshoot_fraction = max(0.0, float(np.max(normalised)) - 1.0)

    distance = np.abs(normalised - 1.0)
    outside = np.nonzero(distance > settling_band)[0]
    if outside.size == 0:
        settling_time = float(t_s[0])
    elif int(outside[-1]) == normalised.size - 1:
        settling_time = math.inf
    else:
        last = int(outside[-1])
        fraction = (distance[last] - settling_band) / (distance[last] - distance[last + 1])
        settling_time = float(t_s[last] + fraction * (t_s[last + 1] - t_s[last]))

    return StepMetrics(
        rise_time=rise_time,
        overshoot=overshoot_fraction * abs(amplitude),
        overshoot_fraction=overshoot_fraction,
        settling_time=settling_time,
    )


def end_effector_errors(
    t_ns: ArrayLike, reference: ArrayLike, position: ArrayLike, params: SMMParameters
) -> Mapping[str, AxisError]:
    """End-effector position errors (Section V.B, Table 6) along x, y, z in mm.

    Args:
        t_ns: Stamps (ns), shape (N,).
        reference: Desired joint position (rad), shape (N, 2).
        position: Actual joint position (rad), shape (N, 2).
        params: Parameters providing the link length L and theta(q) through
            ``smm_dynamics.end_effector_position``.

    Returns:
        ``{"x": AxisError, "y": AxisError, "z": AxisError}``.
    """
    stamps = validated_time(t_ns)
    desired = _validated_joint_array("reference", reference, stamps.size)
    actual = _validated_joint_array("position", position, stamps.size)
    desired_xyz = np.asarray(end_effector_position(desired, params), dtype=np.float64)
    actual_xyz = np.asarray(end_effector_position(actual, params), dtype=np.float64)
    error_mm = (desired_xyz - actual_xyz) * _MM_PER_M
    return {
        axis: AxisError(
            **{row.name: row.of(stamps, error_mm[:, index]) for row in metrics_of(Group.END_EFFECTOR)}
        )
        for index, axis in enumerate(CARTESIAN_AXES)
    }


class Group(Enum):
    """The result a metric is a field of: :class:`JointIndices`, :class:`StepMetrics`, :class:`AxisError`."""

    JOINT = "joint"
    STEP = "step"
    END_EFFECTOR = "end_effector"


class Signal(Enum):
    """The per-step series a metric reduces."""

    TRACKING_ERROR = "tracking_error"
    """q_d - q per joint (rad), q the true position where recorded."""
    TORQUE = "torque"
    """Commanded torque per joint (N m)."""
    POSITION = "position"
    """Joint position (rad), the step response."""
    END_EFFECTOR_ERROR = "end_effector_error"
    """Desired minus actual end-effector position per axis (mm)."""


class Reduction(Enum):
    """How a metric reduces its signal x_k at stamps t_k (s, k = 0..n-1), and what an accumulator keeps."""

    MAX_ABS = "max_abs"
    """max_k |x_k|; state: the running max."""
    MEAN_ABS = "mean_abs"
    """sum_k |x_k| / n; state: the sum and n."""
    RMS_OVER_TIME = "rms_over_time"
    """sqrt(T / (t_{n-1} - t_0)), T = sum_k (x_{k-1}^2 + x_k^2) (t_k - t_{k-1})/2; state: T, x_{k-1}, t_0."""
    INTEGRAL_SQUARE = "integral_square"
    """T as in RMS_OVER_TIME (a trapezoidal integral of x^2, times in s); state: T, x_{k-1}, t_{k-1}."""
    INCREMENT_RMS = "increment_rms"
    """sqrt(sum_k (x_k - x_{k-1})^2 / (n - 1)); state: the sum, x_{k-1}, n."""
    STEP_RESPONSE = "step_response"
    """A field of :func:`step_metrics`: needs the whole series (first crossings, last exit from the band)."""


def _max_abs(t_ns: IntArray, series: FloatArray) -> float:
    return max_abs_error(series)


def _mean_abs(t_ns: IntArray, series: FloatArray) -> float:
    return mean_abs_error(series)


def _increment_rms(t_ns: IntArray, series: FloatArray) -> float:
    return torque_increment_rms(series)


_REDUCTIONS: Mapping[Reduction, Callable[[IntArray, FloatArray], float]] = {
    Reduction.MAX_ABS: _max_abs,
    Reduction.MEAN_ABS: _mean_abs,
    Reduction.RMS_OVER_TIME: rms_error,
    Reduction.INTEGRAL_SQUARE: control_energy,
    Reduction.INCREMENT_RMS: _increment_rms,
}


@dataclass(frozen=True)
class Metric:
    """One metric: a field of :class:`JointIndices`, :class:`StepMetrics` or :class:`AxisError`.

    Attributes:
        name: The field's name, the key in metrics.json.
        group: The result it belongs to.
        signal: The series it reduces.
        reduction: How (the function, and the state a streaming computation keeps).
        unit: Short unit, for tables.
        json_unit: The unit as ``meta.units`` of metrics.json gives it (with what it measures).
        batched: Whether the batched loop (sweeps) computes it, per joint, as column ``{column}_{joint}``.
        column: The batched loop's column stem (default ``name``).
        paper_equation: The paper's equation it is, or "" for the project's own.
        label: How tables name it (default ``name``).
        in_reports: Whether the bag comparison table shows it.
    """

    name: str
    group: Group
    signal: Signal
    reduction: Reduction
    unit: str
    json_unit: str
    batched: bool
    column: str = ""
    paper_equation: str = ""
    label: str = ""
    in_reports: bool = True

    def __post_init__(self) -> None:
        if not self.column:
            object.__setattr__(self, "column", self.name)
        if not self.label:
            object.__setattr__(self, "label", self.name)

    @property
    def function(self) -> Callable[[IntArray, FloatArray], float] | None:
        """``function(t_ns, series) -> value`` over a series; None for a field of :func:`step_metrics`."""
        return _REDUCTIONS.get(self.reduction)

    def of(self, t_ns: IntArray, series: FloatArray) -> float:
        """The metric of ``series`` at the stamps ``t_ns`` (ns), shape (N,) each; not for a step metric."""
        function = self.function
        if function is None:
            raise MetricsInputError(f"{self.name} is a field of step_metrics, not a reduction of one series")
        return function(t_ns, series)


_TRACKING, _TORQUE = Signal.TRACKING_ERROR, Signal.TORQUE
_STEP, _EE = Group.STEP, Group.END_EFFECTOR
METRICS: tuple[Metric, ...] = (
    Metric("Ma", Group.JOINT, _TRACKING, Reduction.MAX_ABS, "rad", "rad", True, paper_equation="42"),
    Metric("Ave", Group.JOINT, _TRACKING, Reduction.MEAN_ABS, "rad", "rad", True, paper_equation="43"),
    Metric("RMS", Group.JOINT, _TRACKING, Reduction.RMS_OVER_TIME, "rad", "rad", True, paper_equation="44"),
    Metric(
        "eps_u",
        Group.JOINT,
        _TORQUE,
        Reduction.INTEGRAL_SQUARE,
        "N^2 m^2 s",
        "N^2 m^2 s (integral of the commanded torque squared)",
        True,
        paper_equation="45",
    ),
    Metric(
        "du_rms",
        Group.JOINT,
        _TORQUE,
        Reduction.INCREMENT_RMS,
        "N m",
        "N m per control step (RMS of the commanded torque's increment; torque smoothness)",
        True,
    ),
    Metric("rise_time", _STEP, Signal.POSITION, Reduction.STEP_RESPONSE, "s", "s (10-90 %)", True),
    Metric(
        "overshoot", _STEP, Signal.POSITION, Reduction.STEP_RESPONSE, "rad", "rad", False, in_reports=False
    ),
    Metric(
        "overshoot_fraction",
        _STEP,
        Signal.POSITION,
        Reduction.STEP_RESPONSE,
        "-",
        "fraction of the step (x100 = %)",
        True,
        column="overshoot",  # the sweeps' column name, which sweep specs name
    ),
    Metric(
        "settling_time",
        _STEP,
        Signal.POSITION,
        Reduction.STEP_RESPONSE,
        "s",
        "s (2 % band; null = not settled)",
        True,
    ),
    Metric("max_mm", _EE, Signal.END_EFFECTOR_ERROR, Reduction.MAX_ABS, "mm", "mm", False, label="max"),
    Metric("rms_mm", _EE, Signal.END_EFFECTOR_ERROR, Reduction.RMS_OVER_TIME, "mm", "mm", False, label="RMS"),
)
"""Every metric, once, in the order of metrics.json and the reports (docs/METRICS.md defines them)."""


def metrics_of(group: Group) -> tuple[Metric, ...]:
    """The rows of :data:`METRICS` in ``group``, in table order."""
    return tuple(row for row in METRICS if row.group is group)


def metric(name: str) -> Metric:
    """The row of :data:`METRICS` named ``name``.

    Raises:
        KeyError: No metric has that name.
    """
    for row in METRICS:
        if row.name == name:
            return row
    raise KeyError(f"unknown metric {name!r}; known: {', '.join(row.name for row in METRICS)}")
