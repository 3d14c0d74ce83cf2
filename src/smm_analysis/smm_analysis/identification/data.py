"""Identification data from a run held in memory: filtered zero-phase, differentiated, rows picked.

Filtering, row selection and their settings: docs/IDENTIFICATION.md, "How the data are prepared".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from smm_analysis.errors import IdentificationInputError, NotEnoughDataError, SaturatedRunError, StopsRunError
from smm_analysis.identification.exclusions import Intervals, Saturation, Stops, flagged_count, flags_of
from smm_analysis.identification.filtering import (
    Filters,
    FilterSettings,
    Segment,
    filters_for,
    smoothed,
    stretch_rows,
    stretches,
)

__all__ = ["Exclusions", "FilterSettings", "PreparedRun", "Segment", "prepare_run"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
_NS_PER_S = 1e9


@dataclass(frozen=True)
class PreparedRun:
    """A run ready for the regressor.

    Attributes:
        name: Where it came from (bag folder), for reports.
        segments: The stretches used.
        settings: The filter settings applied.
        sample_period: Control period (s).
        warnings: What was left out and why, one line each.
    """

    name: str
    segments: tuple[Segment, ...]
    settings: FilterSettings
    sample_period: float
    warnings: tuple[str, ...] = ()

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
    """Filters and differentiates one run held in memory and picks its usable rows.

    ``smm-bag identify`` streams instead (:mod:`smm_analysis.identification.streaming`, the same steps).

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
    commanded = None if command is None else _as_series("command", command, stamps.size)
    time = (stamps - stamps[0]).astype(np.float64) / _NS_PER_S
    filters = filters_for(
        name,
        settings,
        float(np.median(np.diff(stamps))),
        stamps.size,
        float(time[-1]),
        gravity=gravity,
        gravity_sign=gravity_sign,
    )
    saturation = Saturation(np.abs(tau).max(axis=0), np.ptp(tau, axis=0), filters.min_plateau)
    saturation.feed(tau, commanded)
    smooth, velocity = smoothed(filters, q)
    stops = Stops(smooth.min(axis=0), smooth.max(axis=0), filters.min_stop)
    stops.feed(smooth, velocity)
    exclusions = Exclusions(stamps.size, saturation.finish(), stops.finish())
    segments: list[Segment] = []
    rest = 0
    for begin, end in stretches(stamps, filters.period_ns):
        n = end - begin
        if n <= filters.shortest_stretch:
            continue
        segment, resting = stretch_rows(
            filters,
            time[begin:end],
            q[begin:end],
            tau[begin:end],
            offset=0,
            length=n,
            rows=(0, n - 1),
            excluded=exclusions.of(begin + 1, end),
        )
        segments.append(segment)
        rest += resting
    usable = sum(int(segment.use.any(axis=1).sum()) for segment in segments)
    warnings = exclusions.warnings(name, rest, usable, filters)
    return PreparedRun(
        name=name,
        segments=tuple(segments),
        settings=settings,
        sample_period=filters.period,
        warnings=tuple(warnings),
    )


@dataclass(frozen=True)
class Exclusions:
    """The samples of a run left out: saturated and at a stop, as intervals per joint.

    Attributes:
        steps: Samples in the run.
        saturated: Saturated sample intervals per joint.
        stopped: Sample intervals at a stop per joint.
    """

    steps: int
    saturated: tuple[Intervals, Intervals]
    stopped: tuple[Intervals, Intervals]

    def of(self, start: int, stop: int) -> BoolArray:
        """Samples [start, stop) saturated or at a stop, shape (stop - start, 2)."""
        return flags_of(self.saturated, start, stop) | flags_of(self.stopped, start, stop)

    def warnings(self, name: str, rest: int, usable: int, filters: Filters) -> list[str]:
        """What was left out, one line each, given ``rest`` joint rows at rest and ``usable`` rows.

        Raises:
            SaturatedRunError, StopsRunError: More than ``max_excluded`` of the run.
            NotEnoughDataError: Less usable time than ``min_duration``.
        """
        settings = filters.settings
        warnings = _exclusion_warnings(
            name,
            saturated=flagged_count(self.saturated),
            stopped=flagged_count(self.stopped),
            rows=self.steps,
            rest=rest,
            period=filters.period,
            settings=settings,
        )
        if usable * filters.period < settings.min_duration:
            raise NotEnoughDataError(
                f"{name}: {usable * filters.period:.3g} s of usable motion, identification needs at least "
                f"{settings.min_duration:g} s (after leaving out {settings.edge:g} s at the ends of "
                "stretches, joints at rest, saturation and the stops)"
            )
        return warnings


def _exclusion_warnings(
    name: str,
    *,
    saturated: NDArray[np.int64],
    stopped: NDArray[np.int64],
    rows: int,
    rest: int,
    period: float,
    settings: FilterSettings,
) -> list[str]:
    warnings = []
    for label, flagged, error in (
        (
            "the torque saturated (at its largest magnitude, or commanded beyond it)",
            saturated,
            SaturatedRunError,
        ),
        ("a joint at a mechanical stop (position held at its extreme)", stopped, StopsRunError),
    ):
        fractions = flagged / rows
        if fractions.max() > settings.max_excluded:
            joints = [
                f"{joint} {fraction:.0%}"
                for joint, fraction in zip(("alpha", "beta"), fractions, strict=True)
            ]
            raise error(
                f"{name}: {label} for {', '.join(joints)} of the run, more than max_excluded "
                f"{settings.max_excluded:.0%}: record a run within the limits"
            )
        if flagged.any():
            seconds = float(flagged.max()) * period
            warnings.append(f"{name}: left out {seconds:.3g} s with {label}")
    if rest:
        warnings.append(
            f"{name}: left out {rest} joint rows at rest or turning round "
            f"(|q'| < {settings.rest_velocity:g} rad/s and {settings.rest_guard:g} s around)"
        )
    return warnings
