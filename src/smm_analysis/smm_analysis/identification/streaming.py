"""A run of a bag prepared for identification in bounded memory: the steps of ``prepare_run``, piece by piece.

One read of the bag spools the series identification needs (stamps, q, applied and commanded torque: 56
bytes a step) to a temporary file and finds the period and the torque's extremes. The spool is then read in
pieces: the smoothed positions' extremes and saturation, then the stops, then the filtered rows, reduced to
normal equations as they come (:class:`RunSums`); figures read it once more (docs/IDENTIFICATION.md,
"Streaming").
"""

from __future__ import annotations

import itertools
import math
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from smm_bag.manifest import RunManifest

from smm_analysis.errors import IdentificationInputError, MissingSignalsError
from smm_analysis.identification.data import Exclusions
from smm_analysis.identification.exclusions import Saturation, Stops
from smm_analysis.identification.filtering import (
    Filters,
    FilterSettings,
    Segment,
    filters_for,
    smoothed,
    stretch_rows,
)
from smm_analysis.identification.sums import RunSums
from smm_analysis.identification.valve_gain import GainSums
from smm_analysis.runs.envelope import Envelope
from smm_analysis.runs.stream import JOINTS, StepStream

__all__ = ["PIECE_ROWS", "RECORD", "StreamedRun", "draw_fit", "read_run"]

FloatArray = NDArray[np.float64]
RECORD = np.dtype(
    [
        ("t", "<i8"),
        ("q", "<f8", (2,)),
        ("tau", "<f8", (2,)),
        ("command", "<f8", (2,)),
        ("measured", "<f8", (2,)),
    ]
)
"""One spooled step: stamp (ns), measured q (rad), applied, commanded and measured torque (N m; NaN: none)."""
MEASURED_TORQUE = "hw_bridge.measured_torque"
"""The bridge's torque from the load pressure (``hw_bridge_internals`` row ``measured_torque``)."""
PIECE_ROWS = 16_384
"""Rows filtered at once (besides :attr:`Filters.overlap` samples on each side)."""
_NS_PER_S = 1e9


class Spool:
    """The steps of one run in a file of :data:`RECORD`, written once, then read by index."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.steps = 0
        self._file = path.open("wb")

    def append(self, records: NDArray[np.void]) -> None:
        """Appends steps (an array of :data:`RECORD`)."""
        self._file.write(records.tobytes())
        self.steps += int(records.size)

    def close(self) -> None:
        """Ends writing."""
        self._file.close()

    def read(self, start: int, stop: int) -> NDArray[np.void]:
        """Steps [start, stop)."""
        return np.fromfile(self.path, dtype=RECORD, count=stop - start, offset=start * RECORD.itemsize)

    def pieces(self, size: int, overlap: int) -> Iterator[tuple[int, slice, NDArray[np.void]]]:
        """Consecutive pieces of ``size`` steps: (first step, where it lies in the steps read, those steps).

        The steps read reach ``overlap`` steps beyond the piece on each side, where the run has them, and
        number at least 2 ``overlap`` + 1 (the window of a filter), where the run has them.
        """
        for start in range(0, self.steps, size):
            stop = min(start + size, self.steps)
            high = min(stop + overlap, self.steps)
            low = max(min(start - overlap, high - 2 * overlap - 1), 0)
            yield start, slice(start - low, stop - low), self.read(low, high)


@dataclass(frozen=True, eq=False)
class StreamedRun:
    """A run read for identification: its sums, what was left out, and its spool for the figures.

    Attributes:
        name: Where it came from (bag, segment), for reports.
        settings: The filter settings applied.
        sample_period: Control period (s).
        warnings: What was left out and why, one line each.
        sums: Its normal equations.
        steps: Control steps read.
        manifest: The bag's run manifest.
        excitation: Envelope of the measured q and applied torque (``q alpha``, ``tau beta``, ...).
        layout: Its spool and how its rows are made (for :func:`draw_fit`).
        gain: Sums for the valve's gain when the bag has the measured torque at every step, else None.
    """

    name: str
    settings: FilterSettings
    sample_period: float
    warnings: tuple[str, ...]
    sums: RunSums
    steps: int
    manifest: RunManifest
    excitation: Envelope
    layout: _Layout
    gain: GainSums | None = None


@dataclass
class _Scan:
    """What the read of the bag finds: intervals between stamps, torque extremes."""

    first_ns: int | None = None
    last_ns: int = 0
    intervals: Counter[int] | None = None
    low: FloatArray | None = None
    high: FloatArray | None = None
    measured_steps: int = 0

    def add(self, t_ns: NDArray[np.int64], tau: FloatArray) -> None:
        if self.first_ns is None:
            self.first_ns = int(t_ns[0])
            self.intervals = Counter()
            self.low, self.high = tau.min(axis=0), tau.max(axis=0)
        else:
            assert self.low is not None and self.high is not None
            t_ns = np.concatenate([[self.last_ns], t_ns])
            self.low, self.high = np.fmin(self.low, tau.min(axis=0)), np.fmax(self.high, tau.max(axis=0))
        assert self.intervals is not None
        values, counts = np.unique(np.diff(t_ns), return_counts=True)
        self.intervals.update(dict(zip(values.tolist(), counts.tolist(), strict=True)))
        self.last_ns = int(t_ns[-1])

    def median_interval(self) -> float:
        """The median of the stamp intervals (ns), as ``numpy.median`` of them all."""
        assert self.intervals is not None
        total = sum(self.intervals.values())
        middle = [(total - 1) // 2, total // 2]
        values, seen = [], 0
        for value in sorted(self.intervals):
            seen += self.intervals[value]
            while middle and middle[0] < seen:
                values.append(value)
                middle.pop(0)
        return float(values[0] + values[1]) / 2.0


def _spool_bag(stream: StepStream, spool: Spool, excitation: Envelope) -> _Scan:
    """Reads the bag into the spool; refuses steps without a finite position, torque or command."""
    scan = _Scan()
    try:
        for block in stream.blocks():
            if not np.all(np.isfinite(block.applied_torque)):
                raise MissingSignalsError(
                    f"{stream.bag}: joint_states carries no effort (the applied torque) at every step: "
                    "identification needs it; record with a plant that reports it (the simulator and the "
                    "bridge do)"
                )
            for label, values in (("position", block.measured_position), ("command", block.command_torque)):
                if not np.all(np.isfinite(values)):
                    raise IdentificationInputError(f"{stream.bag}: {label} holds NaN or infinite values")
            records = np.empty(block.t_ns.size, dtype=RECORD)
            records["t"], records["q"] = block.t_ns, block.measured_position
            records["tau"], records["command"] = block.applied_torque, block.command_torque
            measured = block.internals.get(MEASURED_TORQUE)
            records["measured"] = math.nan if measured is None else measured
            scan.measured_steps += int(np.all(np.isfinite(records["measured"]), axis=1).sum())
            spool.append(records)
            scan.add(block.t_ns, block.applied_torque)
            assert scan.first_ns is not None
            time = (block.t_ns - scan.first_ns).astype(np.float64) / _NS_PER_S
            series = {f"q {joint}": block.measured_position[:, j] for j, joint in enumerate(JOINTS)}
            series |= {f"tau {joint}": block.applied_torque[:, j] for j, joint in enumerate(JOINTS)}
            excitation.add(time, series)
    finally:
        spool.close()
    return scan


def read_run(
    name: str,
    stream: StepStream,
    spool_path: Path,
    settings: FilterSettings,
    *,
    gravity: float,
    gravity_sign: float,
    block: float,
    progress: Callable[[int, int], None] | None = None,
    piece: int = PIECE_ROWS,
) -> StreamedRun:
    """Reads, filters and reduces one run (a bag or its window), as ``prepare_run`` then ``sums_of``.

    Args:
        name: Label for reports.
        stream: The bag's steps (its window).
        spool_path: Where to spool the steps (a temporary file; removed by the caller).
        settings: Filter settings.
        gravity: g of the regressor (m/s^2).
        gravity_sign: Its sign, as ``SMMParameters.gravity_sign``.
        block: Length of a bootstrap block (s).
        progress: Called with (steps done, steps to do) over the passes after the read.
        piece: Rows (steps) filtered at once.

    Raises:
        BagError: See :class:`StepStream`.
        MissingSignalsError: No applied torque (``joint_states`` effort) at some step.
        IdentificationError: As :func:`prepare_run`.
    """
    spool = Spool(spool_path)
    excitation = Envelope()
    scan = _spool_bag(stream, spool, excitation)
    assert scan.first_ns is not None and scan.low is not None and scan.high is not None
    steps = spool.steps
    measured = scan.measured_steps == steps
    filters = filters_for(
        name,
        settings,
        scan.median_interval(),
        steps,
        (scan.last_ns - scan.first_ns) / _NS_PER_S,
        gravity=gravity,
        gravity_sign=gravity_sign,
    )
    half = filters.window // 2

    def report(done: int) -> None:
        if progress is not None:
            progress(done, 3 * steps)

    # Pass 1: the smoothed positions' extremes, saturation, the stretches.
    peak = np.fmax(np.abs(scan.low), np.abs(scan.high))
    saturation = Saturation(peak, scan.high - scan.low, filters.min_plateau)
    gain = GainSums(block, peak) if measured else None
    low, high = np.full(2, np.inf), np.full(2, -np.inf)
    breaks: list[int] = []
    for start, kept, records in spool.pieces(piece, half):
        smooth = smoothed(filters, records["q"])[0][kept]
        low, high = np.fmin(low, smooth.min(axis=0)), np.fmax(high, smooth.max(axis=0))
        saturation.feed(records["tau"][kept], records["command"][kept])
        if gain is not None:
            time = (records["t"][kept] - scan.first_ns).astype(np.float64) / _NS_PER_S
            gain.add(time, records["measured"][kept], records["tau"][kept])
        before = 1 if kept.start > 0 else 0  # the step before the piece, for the interval into it
        gaps = np.flatnonzero(
            np.diff(records["t"][kept.start - before : kept.stop]) > 1.5 * filters.period_ns
        )
        breaks.extend((start - before + 1 + gaps).tolist())
        report(start + kept.stop - kept.start)
    # Pass 2: the stops.
    stops = Stops(low, high, filters.min_stop)
    for start, kept, records in spool.pieces(piece, half):
        smooth, velocity = smoothed(filters, records["q"])
        stops.feed(smooth[kept], velocity[kept])
        report(steps + start + kept.stop - kept.start)
    exclusions = Exclusions(steps, saturation.finish(), stops.finish())
    bounds = [0, *breaks, steps]
    torque = "measured" if measured else "tau"
    layout = _Layout(
        spool, filters, scan.first_ns, tuple(itertools.pairwise(bounds)), exclusions, piece, torque
    )
    # Pass 3: the rows, into the sums.
    sums = RunSums(name, block)
    rest = usable = done = 0
    for opening, closing, rows, resting in layout.rows():
        if opening:
            sums.start_stretch(float(rows.time[0]))
        sums.add(rows)
        if closing:
            sums.end_stretch()
        rest += resting
        usable += int(rows.use.any(axis=1).sum())
        done += int(rows.time.size)
        report(2 * steps + done)
    warnings = exclusions.warnings(name, rest, usable, filters)
    if 0 < scan.measured_steps < steps:
        warnings.append(
            f"{name}: the measured torque ({MEASURED_TORQUE}) is missing at {steps - scan.measured_steps} of "
            f"{steps} steps: the valve model's torque (joint_states effort) used instead, no valve gain"
        )
    report(3 * steps)
    return StreamedRun(
        name=name,
        settings=settings,
        sample_period=filters.period,
        warnings=tuple(warnings),
        sums=sums,
        steps=steps,
        manifest=stream.manifest,
        excitation=excitation,
        layout=layout,
        gain=gain,
    )


@dataclass(frozen=True, eq=False)
class _Layout:
    """Where a spooled run's rows come from: its filters, stretches and left-out samples."""

    spool: Spool
    filters: Filters
    first_ns: int
    stretches: tuple[tuple[int, int], ...]
    exclusions: Exclusions
    piece: int
    torque: str = "tau"
    """The spooled torque the rows regress on: ``tau`` (the valve model's) or ``measured``."""

    def rows(self) -> Iterator[tuple[bool, bool, Segment, int]]:
        """(first piece of a stretch, last piece, the rows, joint rows at rest) of every long stretch."""
        overlap = self.filters.overlap
        for begin, end in self.stretches:
            n = end - begin
            if n <= self.filters.shortest_stretch:
                continue
            for first in range(0, n - 1, self.piece):
                stop = min(first + self.piece, n - 1)
                low, high = max(first - overlap, 0), min(stop + 1 + overlap, n)
                records = self.spool.read(begin + low, begin + high)
                rows, resting = stretch_rows(
                    self.filters,
                    (records["t"] - self.first_ns).astype(np.float64) / _NS_PER_S,
                    records["q"],
                    records[self.torque],
                    offset=low,
                    length=n,
                    rows=(first, stop),
                    excluded=self.exclusions.of(begin + first + 1, begin + stop + 1),
                )
                yield first == 0, stop == n - 1, rows, resting


def draw_fit(
    run: StreamedRun, theta: FloatArray, progress: Callable[[int, int], None] | None = None
) -> Envelope:
    """Envelope of the filtered torque, the model's (``theta``) and the residual of used and left-out rows.

    Series ``measured alpha``, ``model alpha``, ``used alpha``, ``left out alpha`` (and beta), N m.
    """
    envelope = Envelope()
    done = 0
    for _, _, rows, _ in run.layout.rows():
        predicted = rows.columns @ theta
        residual = rows.torque - predicted
        series: dict[str, FloatArray] = {}
        for j, joint in enumerate(JOINTS):
            used = rows.use[:, j]
            series[f"measured {joint}"] = rows.torque[:, j]
            series[f"model {joint}"] = predicted[:, j]
            series[f"used {joint}"] = np.where(used, residual[:, j], np.nan)
            series[f"left out {joint}"] = np.where(used, np.nan, residual[:, j])
        envelope.add(rows.time, series)
        done += int(rows.time.size)
        if progress is not None:
            progress(done, run.steps)
    return envelope
