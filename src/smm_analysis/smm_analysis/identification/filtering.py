"""How a stretch of a run is filtered and differentiated into regressor rows, whole or in overlapping pieces.

Savitzky-Golay states, the regressor, one zero-phase low-pass on both sides of tau = Y theta; the pieces'
overlap and their tolerance against the whole: docs/IDENTIFICATION.md, "How the data are prepared" and
"Streaming".
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import butter, filtfilt, lfilter, savgol_filter

from smm_analysis.errors import IdentificationInputError, NotEnoughDataError
from smm_analysis.identification.regressor import regressor

__all__ = [
    "TRANSIENT",
    "FilterSettings",
    "Filters",
    "Segment",
    "filters_for",
    "smoothed",
    "stretch_rows",
    "stretches",
]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
_NS_PER_S = 1e9
# A stretch at the torque's largest magnitude counts from this length (s).
_PLATEAU_MIN_DURATION = 0.05
# A joint at a stop (exclusions.Stops) counts from this length (s).
_STOP_MIN_DURATION = 0.2


@dataclass(frozen=True)
class FilterSettings:
    """How a run is filtered and which samples are used (reported with every estimate).

    Attributes:
        cutoff: Corner frequency of the zero-phase Butterworth low-pass (Hz), > 0, below Nyquist.
        order: Order of the Butterworth filter (applied twice by filtfilt), integer >= 1.
        savgol_window: Length of the Savitzky-Golay derivative window (s), > 0.
        savgol_order: Polynomial order of the Savitzky-Golay window, integer >= 2.
        edge: Time left out at both ends of every stretch (filter transients) (s), >= 0.
        rest_velocity: A joint's row is left out while its filtered |q'| is below this (rad/s), >= 0.
        rest_guard: ... and within this time of such a row (turning round, at rest) (s), >= 0.
        min_duration: Least usable time over all stretches (s), > 0.
        max_excluded: Largest fraction of rows saturation or the stops may take before the run is refused,
            in (0, 1].
    """

    cutoff: float = 4.0
    order: int = 4
    savgol_window: float = 0.101
    savgol_order: int = 4
    edge: float = 0.3
    rest_velocity: float = 0.02
    rest_guard: float = 0.25
    min_duration: float = 2.0
    max_excluded: float = 0.2

    def __post_init__(self) -> None:
        for name in ("cutoff", "savgol_window", "min_duration"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        for name in ("edge", "rest_velocity", "rest_guard"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        for name, least in (("order", 1), ("savgol_order", 2)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
        if not 0.0 < self.max_excluded <= 1.0:
            raise ValueError(f"max_excluded must be in (0, 1], got {self.max_excluded!r}")

    def describe(self) -> str:
        """One line for reports."""
        return " ".join(
            (
                f"Savitzky-Golay states (scipy.signal.savgol_filter), window {self.savgol_window:g} s,",
                f"order {self.savgol_order}; zero-phase Butterworth low-pass (scipy.signal.filtfilt),",
                f"order {self.order}, cutoff {self.cutoff:g} Hz, on the regressor and the torques alike;",
                f"{self.edge:g} s left out at each end of a stretch; a joint's rows left out below",
                f"|q'| = {self.rest_velocity:g} rad/s and {self.rest_guard:g} s around",
            )
        )


@dataclass(frozen=True)
class Segment:
    """One contiguous stretch, at the midpoints of its control intervals.

    Attributes:
        time: Midpoint times since the run's first stamp (s), shape (n,).
        position: Filtered q (rad), shape (n, 2).
        velocity: q' (rad/s), shape (n, 2).
        acceleration: q'' (rad/s^2), shape (n, 2).
        torque: Filtered applied torque (N m), shape (n, 2).
        columns: Filtered regressor Y (N m per parameter unit), shape (n, 2, 11).
        use: Which joint rows enter the estimate, shape (n, 2).
    """

    time: FloatArray
    position: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    torque: FloatArray
    columns: FloatArray
    use: BoolArray


def _guarded_rest(slow: BoolArray, period: float, guard_time: float) -> BoolArray:
    """Rows at rest or within ``guard_time`` of a row at rest, per joint.

    At rest and while a joint turns round, the friction is not f_c sign(q') of the filtered q' (the joint
    sticks for a few ms; a plant whose Coulomb term has sign(0) = 0 chatters there), and the low-pass spreads
    that over about 1/cutoff around it.
    """
    guard = round(guard_time / period)
    result = slow.copy()
    if guard == 0:
        return result
    for joint in (0, 1):
        if slow[:, joint].any():
            counts = np.convolve(slow[:, joint].astype(np.float64), np.ones(2 * guard + 1), mode="same")
            result[:, joint] |= counts > 0.5
    return result


def _odd_window(seconds: float, period: float, order: int) -> int:
    window = max(round(seconds / period), order + 2)
    return window if window % 2 == 1 else window + 1


@dataclass(frozen=True)
class Filters:
    """The filters and row rules of one run: its settings at its control period (see :func:`filters_for`).

    Attributes:
        settings: The filter settings.
        period_ns: Control period, the median stamp interval (ns).
        b: Butterworth numerator.
        a: Butterworth denominator.
        window: Savitzky-Golay window (samples, odd).
        edge: Samples left out at each end of a stretch.
        gravity: g of the regressor (m/s^2).
        gravity_sign: Its sign, as ``SMMParameters.gravity_sign``.
    """

    settings: FilterSettings
    period_ns: float
    b: FloatArray
    a: FloatArray
    window: int
    edge: int
    gravity: float
    gravity_sign: float

    @property
    def period(self) -> float:
        """Control period (s)."""
        return self.period_ns / _NS_PER_S

    @property
    def padding(self) -> int:
        """Filtfilt's default padding (samples)."""
        return 3 * max(len(self.a), len(self.b))

    @property
    def min_plateau(self) -> int:
        """Least length of a saturation plateau (samples)."""
        return max(round(_PLATEAU_MIN_DURATION / self.period), 2)

    @property
    def min_stop(self) -> int:
        """Least length of a hold at a stop (samples)."""
        return max(round(_STOP_MIN_DURATION / self.period), 2)

    @property
    def shortest_stretch(self) -> int:
        """A stretch of at most this many samples is too short to filter and is left out."""
        return max(2 * self.edge + self.window, self.padding + 1)

    @property
    def overlap(self) -> int:
        """Samples each side of a piece of a stretch so that its rows equal the whole stretch's.

        The low-pass's start and end transients at the cut are bounded by the tail sum of its impulse
        response times the signal's range; this is where that tail falls below :data:`TRANSIENT`, plus the
        Savitzky-Golay half window and the rest guard (docs/IDENTIFICATION.md, "Streaming").
        """
        tail = _impulse_tail(self.b, self.a)
        decay = int(np.argmax(tail < TRANSIENT))
        return decay + self.window // 2 + round(self.settings.rest_guard / self.period) + 2

    @property
    def piece_tolerance(self) -> float:
        """Bound on |a filtered value from a piece - from the whole stretch| / the series' largest |value|.

        Each of the two runs of the forward and the backward pass rounds differently once started from
        different states: u * sum|a| * sum|g| per pass (g: impulse response of 1/A(z), the rounding's path
        to the output), four such, plus each pass's transient at the cut, at most TRANSIENT times an input
        difference of twice the range (docs/IDENTIFICATION.md).
        """
        unit = float(np.finfo(np.float64).eps) / 2.0
        noise_gain = float(np.abs(_impulse_response(np.ones(1), self.a)).sum())
        return 4.0 * unit * float(np.abs(self.a).sum()) * noise_gain + 4.0 * TRANSIENT


TRANSIENT = 1e-16
"""Tail sum of the low-pass's impulse response beyond the overlap (relative size of the cut's transient)."""


def _impulse_response(b: FloatArray, a: FloatArray) -> FloatArray:
    """Impulse response of b/a until it has decayed below TRANSIENT / 100 of its largest value."""
    rho = float(np.max(np.abs(np.roots(a))))
    length = math.ceil(math.log(TRANSIENT / 100.0) / math.log(rho)) + 100 * len(a)
    response: FloatArray = lfilter(b, a, np.r_[1.0, np.zeros(length - 1)])
    return response


def _impulse_tail(b: FloatArray, a: FloatArray) -> FloatArray:
    """sum_{i >= k} |h_i| for each k."""
    tail: FloatArray = np.cumsum(np.abs(_impulse_response(b, a))[::-1])[::-1]
    return tail


def filters_for(
    name: str,
    settings: FilterSettings,
    period_ns: float,
    steps: int,
    duration: float,
    *,
    gravity: float,
    gravity_sign: float,
) -> Filters:
    """The filters of a run of ``steps`` stamps over ``duration`` (s), ``period_ns`` apart (median).

    Raises:
        IdentificationInputError: The cutoff is not below the Nyquist frequency.
        NotEnoughDataError: Too few steps to filter.
    """
    period = period_ns / _NS_PER_S
    if not settings.cutoff < 0.5 / period:
        raise IdentificationInputError(
            f"cutoff {settings.cutoff:g} Hz is not below the Nyquist frequency {0.5 / period:g} Hz"
        )
    b, a = butter(settings.order, settings.cutoff, fs=1.0 / period)
    filters = Filters(
        settings=settings,
        period_ns=period_ns,
        b=np.asarray(b, dtype=np.float64),
        a=np.asarray(a, dtype=np.float64),
        window=_odd_window(settings.savgol_window, period, settings.savgol_order),
        edge=round(settings.edge / period),
        gravity=gravity,
        gravity_sign=gravity_sign,
    )
    if steps <= max(filters.padding, filters.window) + 2 * filters.edge:
        raise NotEnoughDataError(
            f"{name}: {steps} control steps ({duration:.3g} s), too short to filter and identify "
            f"(at least {settings.min_duration:g} s of motion needed)"
        )
    return filters


def smoothed(filters: Filters, q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Savitzky-Golay q (rad) and q' (rad/s) of consecutive samples, shape (n, 2) each (finds the stops).

    Savitzky-Golay, not the Butterworth: the low-pass rings at the corner a stop makes.
    """
    order, period = filters.settings.savgol_order, filters.period
    smooth = savgol_filter(q, filters.window, order, axis=0)
    velocity = savgol_filter(q, filters.window, order, deriv=1, delta=period, axis=0)
    return smooth, velocity


def stretch_rows(
    filters: Filters,
    time: FloatArray,
    q: FloatArray,
    tau: FloatArray,
    *,
    offset: int,
    length: int,
    rows: tuple[int, int],
    excluded: BoolArray,
) -> tuple[Segment, int]:
    """Rows ``rows`` [first, stop) of a stretch of ``length`` samples, from its samples [offset, offset + n).

    Row k is the interval from sample k to k + 1 of the stretch. Given the whole stretch the rows are exact;
    given :attr:`Filters.overlap` samples more on each side (where the stretch has them) they agree to
    :data:`TRANSIENT` (docs/IDENTIFICATION.md, "Streaming").

    Args:
        filters: The run's filters.
        time: Times since the run's first stamp (s), shape (n,).
        q: Measured positions (rad), shape (n, 2).
        tau: Applied torques (N m), shape (n, 2).
        offset: Index of the first sample given in the stretch.
        length: Samples in the stretch.
        rows: The rows wanted, stretch indices.
        excluded: Saturated or at a stop, of the rows' end samples, shape (stop - first, 2).

    Returns:
        The rows, and how many joint rows were left out at rest (within the edges).
    """
    settings, period = filters.settings, filters.period
    n = time.size
    # Savitzky-Golay states (their passband is far above the cutoff), then one low-pass on both sides.
    q_s, qd, qdd = (
        savgol_filter(q, filters.window, settings.savgol_order, deriv=deriv, delta=period, axis=0)
        for deriv in (0, 1, 2)
    )
    b, a = filters.b, filters.a
    y = regressor(q_s, qd, qdd, gravity=filters.gravity, gravity_sign=filters.gravity_sign)
    columns = filtfilt(b, a, y, axis=0)
    tau_f = filtfilt(b, a, tau, axis=0)
    q_f = filtfilt(b, a, q_s, axis=0)
    qd = filtfilt(b, a, qd, axis=0)
    qdd = filtfilt(b, a, qdd, axis=0)
    # Interval k runs from stamp k-1 to stamp k: states at its midpoint, torque recorded at stamp k.
    mid = (slice(0, n - 1), slice(1, n))
    velocity = 0.5 * (qd[mid[0]] + qd[mid[1]])
    resting = _guarded_rest(np.abs(velocity) < settings.rest_velocity, period, settings.rest_guard)
    first, stop = rows[0] - offset, rows[1] - offset
    index = np.arange(rows[0], rows[1])
    keep = (index >= max(filters.edge - 1, 0)) & (index < length - 1 - filters.edge)
    keep = np.repeat(keep[:, None], 2, axis=1)
    resting = resting[first:stop]
    part = slice(first, stop)
    segment = Segment(
        time=0.5 * (time[mid[0]] + time[mid[1]])[part],
        position=0.5 * (q_f[mid[0]] + q_f[mid[1]])[part],
        velocity=velocity[part],
        acceleration=0.5 * (qdd[mid[0]] + qdd[mid[1]])[part],
        torque=tau_f[1:][part],
        columns=0.5 * (columns[mid[0]] + columns[mid[1]])[part],
        use=keep & ~resting & ~excluded,
    )
    return segment, int((resting & keep).sum())


def stretches(t_ns: NDArray[np.int64], period_ns: float) -> list[tuple[int, int]]:
    """Runs of steps without a missing one, [start, stop) indices into ``t_ns``."""
    breaks = np.flatnonzero(np.diff(t_ns) > 1.5 * period_ns) + 1
    bounds = [0, *breaks.tolist(), t_ns.size]
    return list(itertools.pairwise(bounds))
