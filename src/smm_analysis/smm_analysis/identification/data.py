"""Identification data from a run: positions and applied torques, filtered zero-phase, differentiated.

Filtering, row selection and their settings: docs/IDENTIFICATION.md, "How the data are prepared".
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import butter, filtfilt, savgol_filter

from smm_analysis.errors import IdentificationInputError, NotEnoughDataError, SaturatedRunError, StopsRunError
from smm_analysis.identification.regressor import regressor

__all__ = ["FilterSettings", "PreparedRun", "Segment", "prepare_run"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
_NS_PER_S = 1e9
# A stretch at the torque's largest magnitude counts from this length (s).
_PLATEAU_MIN_DURATION = 0.05
# A joint at a stop: within this fraction of its range from an extreme, |q'| below _STOP_VELOCITY, this long.
_STOP_BAND = 0.01
_STOP_VELOCITY = 0.02
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


@dataclass(frozen=True)
class PreparedRun:
    """A run ready for the regressor.

    Attributes:
        name: Where it came from (bag folder), for reports.
        segments: The stretches used.
        settings: The filter settings applied.
        sample_period: Control period (s).
        warnings: What was left out and why, one line each.
        raw_time: Stamps since the first (s), shape (N,), for plots.
        raw_position: Measured positions (rad), shape (N, 2), for plots.
        raw_torque: Applied torques (N m), shape (N, 2), for plots.
    """

    name: str
    segments: tuple[Segment, ...]
    settings: FilterSettings
    sample_period: float
    warnings: tuple[str, ...] = ()
    raw_time: FloatArray = field(default_factory=lambda: np.zeros(0))
    raw_position: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    raw_torque: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def used_rows(self) -> int:
        """Joint rows entering the estimate."""
        return int(sum(int(segment.use.sum()) for segment in self.segments))


def _as_series(name: str, value: ArrayLike, length: int | None) -> FloatArray:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 2 or (length is not None and array.shape[0] != length):
        expected = f"({length}, 2)" if length is not None else "(N, 2)"
        raise IdentificationInputError(f"{name} must have shape {expected}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise IdentificationInputError(f"{name} holds NaN or infinite values")
    return array


def _plateaus(
    values: FloatArray, level: float, min_samples: int, tolerance: float, *, inner_only: bool = False
) -> BoolArray:
    """Samples in runs of >= min_samples consecutive samples with |values - level| <= tolerance.

    ``inner_only``: runs touching the first or the last sample are not counted (rest before or after).
    """
    near = np.abs(values - level) <= tolerance
    flagged = np.zeros_like(near)
    start = None
    for index, value in enumerate([*near.tolist(), False]):
        if value and start is None:
            start = index
        elif not value and start is not None:
            touches_end = start == 0 or index == near.size
            if index - start >= min_samples and not (inner_only and touches_end):
                flagged[start:index] = True
            start = None
    return flagged


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


def _at_stops(q: FloatArray, period: float, window: int, order: int) -> BoolArray:
    """Samples where a joint is held at an extreme of its range (a stop) for _STOP_MIN_DURATION or more.

    A hold at the start or the end of the run is the rest before or after the motion, not a stop.
    """
    # Savitzky-Golay, not the Butterworth: the low-pass rings at the corner a stop makes.
    smooth = savgol_filter(q, window, order, axis=0)
    velocity = savgol_filter(q, window, order, deriv=1, delta=period, axis=0)
    stopped = np.zeros_like(q, dtype=bool)
    min_samples = max(round(_STOP_MIN_DURATION / period), 2)
    for joint in (0, 1):
        low, high = float(smooth[:, joint].min()), float(smooth[:, joint].max())
        band = _STOP_BAND * max(high - low, 1e-9)
        slow = np.abs(velocity[:, joint]) < _STOP_VELOCITY
        for extreme in (low, high):
            held = slow & (np.abs(smooth[:, joint] - extreme) <= band)
            stopped[:, joint] |= _plateaus(held.astype(np.float64), 1.0, min_samples, 0.0, inner_only=True)
    return stopped


def _stretches(t_ns: NDArray[np.int64], period_ns: float) -> list[slice]:
    breaks = np.flatnonzero(np.diff(t_ns) > 1.5 * period_ns) + 1
    bounds = [0, *breaks.tolist(), t_ns.size]
    return [slice(begin, end) for begin, end in itertools.pairwise(bounds)]


def _odd_window(seconds: float, period: float, order: int) -> int:
    window = max(round(seconds / period), order + 2)
    return window if window % 2 == 1 else window + 1


def prepare_run(
    name: str,
    t_ns: ArrayLike,
    position: ArrayLike,
    torque: ArrayLike,
    settings: FilterSettings | None = None,
    *,
    gravity: float = 9.81,
    gravity_sign: float = 1.0,
    command: ArrayLike | None = None,
) -> PreparedRun:
    """Filters and differentiates one run and picks its usable rows.

    Args:
        name: Label for reports (the bag folder).
        t_ns: Stamps of the control steps (ns), strictly increasing, shape (N,).
        position: Measured joint positions (rad), shape (N, 2).
        torque: Applied torque over the interval before each stamp (N m), shape (N, 2).
        settings: Filter settings (default :class:`FilterSettings`).
        gravity: g of the regressor's gravity column (m/s^2).
        gravity_sign: Its sign, as ``SMMParameters.gravity_sign``.
        command: The commanded torque at each stamp (N m), shape (N, 2), if known: a command beyond the
            largest torque ever applied (for 50 ms or more) is saturation too, also when a valve's lag
            keeps the applied torque from sitting exactly at its limit.

    Returns:
        The prepared run, with a warning per kind of rows left out.

    Raises:
        IdentificationInputError: Malformed arrays (shapes, NaN, stamps not increasing).
        NotEnoughDataError: Less usable time than ``settings.min_duration``.
        SaturatedRunError: The torque sits at its largest magnitude for more than ``max_excluded``.
        StopsRunError: A joint sits at a position extreme (a stop) for more than ``max_excluded``.
    """
    settings = settings if settings is not None else FilterSettings()
    stamps = np.asarray(t_ns)
    if stamps.ndim != 1 or stamps.size < 2 or not np.issubdtype(stamps.dtype, np.integer):
        raise IdentificationInputError(f"t_ns must be a 1-D integer array of >= 2 stamps, got {stamps.shape}")
    stamps = stamps.astype(np.int64)
    if np.any(np.diff(stamps) <= 0):
        raise IdentificationInputError("t_ns must be strictly increasing")
    q = _as_series("position", position, stamps.size)
    tau = _as_series("torque", torque, stamps.size)
    period_ns = float(np.median(np.diff(stamps)))
    period = period_ns / _NS_PER_S
    if not settings.cutoff < 0.5 / period:
        raise IdentificationInputError(
            f"cutoff {settings.cutoff:g} Hz is not below the Nyquist frequency {0.5 / period:g} Hz"
        )
    time = (stamps - stamps[0]).astype(np.float64) / _NS_PER_S
    b, a = butter(settings.order, settings.cutoff, fs=1.0 / period)
    window = _odd_window(settings.savgol_window, period, settings.savgol_order)
    min_plateau = max(round(_PLATEAU_MIN_DURATION / period), 2)
    padding = 3 * max(len(a), len(b))
    if stamps.size <= max(padding, window) + 2 * round(settings.edge / period):
        raise NotEnoughDataError(
            f"{name}: {stamps.size} control steps ({time[-1]:.3g} s), too short to filter and identify "
            f"(at least {settings.min_duration:g} s of motion needed)"
        )
    edge = round(settings.edge / period)
    # Saturation: a torque clipped by a limit sits exactly at its largest magnitude.
    saturated = np.zeros_like(tau, dtype=bool)
    for joint in (0, 1):
        magnitude = np.abs(tau[:, joint])
        peak = float(magnitude.max())
        if np.ptp(tau[:, joint]) <= 1e-9 * max(peak, 1e-12):
            continue  # a constant torque (a joint not driven) is not a clipped one; the rank check names it
        saturated[:, joint] = _plateaus(magnitude, peak, min_plateau, 1e-9 * max(peak, 1e-12))
    if command is not None:
        commanded = np.abs(_as_series("command", command, stamps.size))
        beyond = (commanded > 1.01 * np.abs(tau).max(axis=0)).astype(np.float64)
        for joint in (0, 1):
            saturated[:, joint] |= _plateaus(beyond[:, joint], 1.0, min_plateau, 0.0)
    stopped = _at_stops(q, period, window, settings.savgol_order)
    segments: list[Segment] = []
    counts = {"edges": 0, "rest": 0}
    for stretch in _stretches(stamps, period_ns):
        n = stretch.stop - stretch.start
        if n <= max(2 * edge + window, padding + 1):
            counts["edges"] += n
            continue
        # Savitzky-Golay states (their passband is far above the cutoff), then one low-pass on both sides.
        q_s, qd, qdd = (
            savgol_filter(q[stretch], window, settings.savgol_order, deriv=deriv, delta=period, axis=0)
            for deriv in (0, 1, 2)
        )
        columns = filtfilt(b, a, regressor(q_s, qd, qdd, gravity=gravity, gravity_sign=gravity_sign), axis=0)
        tau_f = filtfilt(b, a, tau[stretch], axis=0)
        q_f = filtfilt(b, a, q_s, axis=0)
        qd = filtfilt(b, a, qd, axis=0)
        qdd = filtfilt(b, a, qdd, axis=0)
        # Interval k runs from stamp k-1 to stamp k: states at its midpoint, torque recorded at stamp k.
        mid = (slice(0, n - 1), slice(1, n))
        keep = np.ones((n - 1, 2), dtype=bool)
        keep[: max(edge - 1, 0)] = False
        keep[n - 1 - edge :] = False
        counts["edges"] += int((~keep).sum()) // 2 + 1
        velocity = 0.5 * (qd[mid[0]] + qd[mid[1]])
        resting = _guarded_rest(np.abs(velocity) < settings.rest_velocity, period, settings.rest_guard)
        counts["rest"] += int((resting & keep).sum())
        excluded = saturated[stretch][1:] | stopped[stretch][1:]
        segments.append(
            Segment(
                time=0.5 * (time[stretch][:-1] + time[stretch][1:]),
                position=0.5 * (q_f[mid[0]] + q_f[mid[1]]),
                velocity=velocity,
                acceleration=0.5 * (qdd[mid[0]] + qdd[mid[1]]),
                torque=tau_f[1:],
                columns=0.5 * (columns[mid[0]] + columns[mid[1]]),
                use=keep & ~resting & ~excluded,
            )
        )
    warnings = _exclusion_warnings(
        name, saturated=saturated, stopped=stopped, counts=counts, period=period, settings=settings
    )
    usable = sum(float(segment.use.any(axis=1).sum()) for segment in segments) * period
    if usable < settings.min_duration:
        raise NotEnoughDataError(
            f"{name}: {usable:.3g} s of usable motion, identification needs at least "
            f"{settings.min_duration:g} s (after leaving out {settings.edge:g} s at the ends of stretches, "
            f"joints at rest, saturation and the stops)"
        )
    return PreparedRun(
        name=name,
        segments=tuple(segments),
        settings=settings,
        sample_period=period,
        warnings=tuple(warnings),
        raw_time=time,
        raw_position=q,
        raw_torque=tau,
    )


def _exclusion_warnings(
    name: str,
    *,
    saturated: BoolArray,
    stopped: BoolArray,
    counts: dict[str, int],
    period: float,
    settings: FilterSettings,
) -> list[str]:
    warnings = []
    rows = saturated.shape[0]
    for label, flags, error in (
        (
            "the torque saturated (at its largest magnitude, or commanded beyond it)",
            saturated,
            SaturatedRunError,
        ),
        ("a joint at a mechanical stop (position held at its extreme)", stopped, StopsRunError),
    ):
        fractions = flags.sum(axis=0) / rows
        if fractions.max() > settings.max_excluded:
            joints = [
                f"{joint} {fraction:.0%}"
                for joint, fraction in zip(("alpha", "beta"), fractions, strict=True)
            ]
            raise error(
                f"{name}: {label} for {', '.join(joints)} of the run, more than max_excluded "
                f"{settings.max_excluded:.0%}: record a run within the limits"
            )
        if flags.any():
            seconds = float(flags.sum(axis=0).max()) * period
            warnings.append(f"{name}: left out {seconds:.3g} s with {label}")
    if counts["rest"]:
        warnings.append(
            f"{name}: left out {counts['rest']} joint rows at rest or turning round "
            f"(|q'| < {settings.rest_velocity:g} rad/s and {settings.rest_guard:g} s around)"
        )
    return warnings
