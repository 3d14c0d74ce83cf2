"""identify streamed: a bag read in pieces agrees with the run held in memory within the stated tolerance,
in memory that does not grow with the bag; windows and segments of a bag are runs of their own."""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from bag.bag_helpers import gain_event
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_analysis.closed_loop import Trajectory
from smm_analysis.identification import (
    EstimationSettings,
    FilterSettings,
    Identification,
    identify,
    prepare_run,
)
from smm_analysis.identification.estimate import estimate
from smm_analysis.identification.exclusions import Plateaus
from smm_analysis.identification.filtering import filters_for, stretch_rows
from smm_analysis.identification.streaming import StreamedRun, _Scan, read_run
from smm_analysis.identification.truth import draw_plant, simulate_excitation
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_analysis.runs.recorded import load_run
from smm_analysis.runs.segments import find_segments
from smm_analysis.runs.stream import StepStream
from smm_bag.cli import main

PLANT = draw_plant(3)
BOOTSTRAP = EstimationSettings(bootstrap=40)
PIECE = 1500
"""Rows per piece in the comparisons: several cuts in an 11 s run."""


@pytest.fixture(scope="module")
def excitation() -> Trajectory:
    return simulate_excitation(PLANT, seed=3, noisy=True)


@pytest.fixture(scope="module")
def bag(excitation: Trajectory, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("streaming") / "excite"
    write_trajectory_bag(excitation, path, internals=False)
    return path


def _streamed(bag: Path, spool: Path, *, piece: int = PIECE, stream: StepStream | None = None) -> StreamedRun:
    return read_run(
        str(bag),
        stream if stream is not None else StepStream(bag),
        spool,
        FilterSettings(),
        gravity=9.81,
        gravity_sign=1.0,
        block=BOOTSTRAP.block,
        piece=piece,
    )


def _in_memory(bag: Path) -> tuple[Identification, list[float], float, float]:
    """The computation in memory; the weighted column norms, the largest crest factor, sin(theta)."""
    run = load_run(bag)
    assert run.applied_torque is not None
    prepared = prepare_run(
        str(bag), run.t_ns, run.measured_position, run.applied_torque, command=run.command_torque
    )
    result = identify([prepared], settings=BOOTSTRAP)
    columns = np.concatenate([segment.columns for segment in prepared.segments])
    torque = np.concatenate([segment.torque for segment in prepared.segments])
    use = np.concatenate([segment.use for segment in prepared.segments])
    residual = torque - columns @ result.theta
    weights = [1.0 / math.sqrt(float(np.mean(residual[use[:, j], j] ** 2))) for j in (0, 1)]
    weighted = [weights[j] * columns[use[:, j], j, :] for j in (0, 1)]
    target = [weights[j] * torque[use[:, j], j] for j in (0, 1)]
    scale = np.sqrt(sum(np.sum(part**2, axis=0) for part in weighted))
    rows = sum(part.shape[0] for part in weighted)
    # Crest factor: the largest |value| of a filtered series (all rows) against its RMS over the used rows.
    crest = max(
        *(
            float(np.abs(weights[j] * columns[:, j, i]).max() * math.sqrt(rows) / scale[i])
            for i in range(scale.size)
            for j in (0, 1)
            if scale[i] > 0
        ),
        *(
            float(np.abs(weights[j] * torque[:, j]).max() * math.sqrt(rows))
            / float(np.linalg.norm(np.concatenate(target)))
            for j in (0, 1)
        ),
    )
    sine = float(np.linalg.norm(np.concatenate([weights[j] * residual[use[:, j], j] for j in (0, 1)])))
    sine /= float(np.linalg.norm(np.concatenate(target)))
    return result, scale.tolist(), crest, sine


def _assert_within_the_stated_tolerance(bag: Path, spool: Path) -> StreamedRun:
    """The bound of docs/IDENTIFICATION.md ("Streaming"): per filtered value delta = piece tolerance x crest
    factor relative to its column's norm; least squares (Golub and Van Loan, thm. 5.3.1) with the weights'
    own perturbation: rho = delta sqrt(11) (2 kappa / cos t + tan t kappa^2) + 2 delta kappa."""
    memory, scale, crest, sine = _in_memory(bag)
    run = _streamed(bag, spool)
    assert sum(1 for _ in run.layout.rows()) >= 5  # the run was cut into pieces
    streamed = estimate([run.sums], settings=BOOTSTRAP)
    assert streamed.rows == memory.rows
    assert run.warnings == prepare_run(str(bag), *_arrays(bag)).warnings
    delta = run.layout.filters.piece_tolerance * crest
    cosine, tangent = math.sqrt(1.0 - sine**2), sine / math.sqrt(1.0 - sine**2)

    def bound(kappa: float) -> float:
        return delta * math.sqrt(11) * (2 * kappa / cosine + tangent * kappa**2) + 2 * delta * kappa

    scaled = np.asarray(scale)
    rho = bound(memory.condition_number)
    difference = np.linalg.norm((streamed.theta - memory.theta) * scaled)
    assert difference <= rho * np.linalg.norm(memory.theta * scaled)
    assert abs(streamed.condition_number - memory.condition_number) <= memory.condition_number * (
        2 * delta * math.sqrt(11) * memory.condition_number
    )
    for mine, theirs in zip(streamed.fits[0].nrmse, memory.fits[0].nrmse, strict=True):
        assert abs(mine - theirs) <= 2 * delta * math.sqrt(11) + rho
    # Each replicate obeys the bound with its own condition number; replicates lie within 10 standard
    # errors of the estimate; a standard deviation moves by at most sqrt(B / (B - 1)) x the largest move.
    largest = bound(memory.bootstrap_condition) * (
        np.linalg.norm(memory.theta * scaled) + 10 * np.linalg.norm(memory.standard_error * scaled)
    )
    per_parameter = largest / scaled
    factor = math.sqrt(BOOTSTRAP.bootstrap / (BOOTSTRAP.bootstrap - 1))
    assert np.all(np.abs(streamed.standard_error - memory.standard_error) <= factor * per_parameter)
    assert np.all(np.abs(streamed.interval - memory.interval) <= per_parameter[:, None])
    return run


def test_a_bag_streamed_in_pieces_agrees_with_the_run_in_memory_within_the_stated_tolerance(
    bag: Path, tmp_path: Path
) -> None:
    _assert_within_the_stated_tolerance(bag, tmp_path / "spool")


def test_a_gap_saturation_and_a_stop_are_found_in_pieces_as_in_memory(
    excitation: Trajectory, tmp_path: Path
) -> None:
    """Beta held at its largest position for 0.5 s (that step repeated), alpha's applied torque at its peak
    for 0.1 s, then 50 steps missing (two stretches)."""
    n = excitation.t_ns.size
    top = int(np.argmax(excitation.measured_position[:, 1]))
    assert 1000 < top < n - 1000
    order = np.r_[np.arange(top), np.full(500, top), np.arange(top, n)]
    keep = np.ones(order.size, dtype=bool)
    keep[3000:3050] = False
    order = order[keep]
    period = round(excitation.control_period * 1e9)
    fields = {
        name: value[order]
        for name, value in vars(excitation).items()
        if isinstance(value, np.ndarray) and value.shape[:1] == (n,)
    }
    fields["t_ns"] = excitation.t_ns[0] + period * np.flatnonzero(keep)
    fields["applied_torque"][4000:4100, 0] = np.abs(excitation.applied_torque[:, 0]).max()
    internals = {name: values[order] for name, values in excitation.internals.items()}
    edited = dataclasses.replace(excitation, **fields, internals=internals)
    path = tmp_path / "edited"
    write_trajectory_bag(edited, path, internals=False)
    run = _assert_within_the_stated_tolerance(path, tmp_path / "spool")
    assert len(run.layout.stretches) == 2
    assert any("saturated" in warning for warning in run.warnings)
    assert any("stop" in warning for warning in run.warnings)


def _arrays(bag: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    run = load_run(bag)
    assert run.applied_torque is not None
    return run.t_ns, run.measured_position, run.applied_torque


def test_rows_of_pieces_are_the_whole_stretchs_within_the_piece_tolerance(bag: Path) -> None:
    """Each filtered series of every piece within Filters.piece_tolerance of its largest |value|."""
    t_ns, q, tau = _arrays(bag)
    time = (t_ns - t_ns[0]) / 1e9
    filters = filters_for("run", FilterSettings(), 1e6, time.size, time[-1], gravity=9.81, gravity_sign=1.0)
    n, overlap = time.size, filters.overlap
    excluded = np.zeros((n - 1, 2), dtype=bool)
    whole, _ = stretch_rows(filters, time, q, tau, offset=0, length=n, rows=(0, n - 1), excluded=excluded)
    for first in range(0, n - 1, 1000):
        stop = min(first + 1000, n - 1)
        low, high = max(first - overlap, 0), min(stop + 1 + overlap, n)
        piece, _ = stretch_rows(
            filters,
            time[low:high],
            q[low:high],
            tau[low:high],
            offset=low,
            length=n,
            rows=(first, stop),
            excluded=excluded[first:stop],
        )
        assert np.array_equal(piece.time, whole.time[first:stop])
        assert np.array_equal(piece.use, whole.use[first:stop])
        for name in ("position", "velocity", "acceleration", "torque", "columns"):
            mine, theirs = getattr(piece, name), getattr(whole, name)
            largest = np.abs(theirs).max(axis=0)
            assert np.all(np.abs(mine - theirs[first:stop]) <= filters.piece_tolerance * largest), name


def test_one_piece_is_the_run_in_memory_exactly(bag: Path, tmp_path: Path) -> None:
    memory = _in_memory(bag)[0]
    streamed = estimate([_streamed(bag, tmp_path / "spool", piece=1_000_000).sums], settings=BOOTSTRAP)
    assert np.array_equal(streamed.theta, memory.theta)
    assert np.array_equal(streamed.interval, memory.interval)


def _peak(bag: Path, spool: Path) -> int:
    """Peak of Python's allocations reading ``bag`` (in small batches, so that a short bag reaches them)."""
    tracemalloc.start()
    try:
        _streamed(bag, spool, piece=2000, stream=StepStream(bag, read_batch=4096, block_steps=2048))
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_memory_does_not_grow_with_the_bag(excitation: Trajectory, tmp_path: Path) -> None:
    """2 and 6 copies of the run back to back: only the bootstrap blocks' sums grow (about 2.6 kB a second
    of run, 1 % of the peak here); a run held in memory would triple."""
    short, long = tmp_path / "short", tmp_path / "long"
    write_trajectory_bag(excitation, short, internals=False, repeat=2)
    write_trajectory_bag(excitation, long, internals=False, repeat=6)
    assert _peak(long, tmp_path / "long.spool") <= 1.1 * _peak(short, tmp_path / "short.spool")


@pytest.fixture(scope="module")
def two_experiments(excitation: Trajectory, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int]:
    """The excitation twice in one bag, a gain change between: returns the bag and the change's stamp."""
    period = round(excitation.control_period * 1e9)
    change = int(excitation.t_ns[-1] - excitation.t_ns[0]) + period
    path = tmp_path_factory.mktemp("two") / "day"
    write_trajectory_bag(
        excitation, path, internals=False, then=(excitation,), parameter_events=[(change, gain_event(change))]
    )
    return path, change


def test_a_window_is_identified_as_the_run_alone(
    two_experiments: tuple[Path, int], bag: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    day, change = two_experiments
    assert main(["identify", str(bag), "--bootstrap", "20", "--quiet"]) == 0
    alone = capsys.readouterr().out
    window = ["--start", "0", "--end", f"{change / 1e9:.9f}"]
    assert main(["identify", str(day), *window, "--bootstrap", "20", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert re.sub(rf"{re.escape(str(day))} \[--start 0 --end [0-9.]+\]", str(bag), printed) == alone


def test_segments_are_runs_of_their_own(
    two_experiments: tuple[Path, int], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    day, _ = two_experiments
    assert len(find_segments(day).segments) == 2
    out = tmp_path / "out"
    assert main(["identify", str(day), "--segments", "--bootstrap", "20", "--quiet", "--out", str(out)]) == 0
    fits = [line for line in capsys.readouterr().out.splitlines() if line.startswith("NRMSE")]
    assert len(fits) == 2 and "segment 1" in fits[0] and "segment 2" in fits[1]
    assert sorted(path.name for path in out.glob("torque_*.png")) == [
        "torque_identification1.png",
        "torque_identification2.png",
    ]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--segments", "--start", "1"], "--segments"),
        (["--start", "soon"], "seconds"),
        (["--start", "5", "--end", "2"], "after"),
    ],
)
def test_bad_window_options_are_usage_errors(
    bag: Path, options: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(bag), *options]) == 2
    assert message in capsys.readouterr().err


def _plateaus_reference(flags: list[bool], min_samples: int, inner_only: bool) -> list[tuple[int, int]]:
    """The specification: maximal runs of True, >= min_samples long, not touching an end if inner_only."""
    found, start = [], None
    for index, value in enumerate([*flags, False]):
        if value and start is None:
            start = index
        elif not value and start is not None:
            touches = start == 0 or index == len(flags)
            if index - start >= min_samples and not (inner_only and touches):
                found.append((start, index))
            start = None
    return found


@settings(max_examples=200, deadline=None)
@given(
    flags=st.lists(st.booleans(), min_size=1, max_size=60),
    cuts=st.lists(st.integers(0, 60), max_size=6),
    min_samples=st.integers(1, 5),
    inner_only=st.booleans(),
)
def test_plateaus_fed_in_pieces_are_those_of_the_whole(
    flags: list[bool], cuts: list[int], min_samples: int, inner_only: bool
) -> None:
    plateaus = Plateaus(min_samples, inner_only=inner_only)
    bounds = sorted({0, len(flags), *(cut for cut in cuts if cut < len(flags))})
    for begin, end in itertools.pairwise(bounds):
        plateaus.feed(np.array(flags[begin:end], dtype=bool))
    assert plateaus.finish() == _plateaus_reference(flags, min_samples, inner_only)


@settings(max_examples=100, deadline=None)
@given(
    intervals=st.lists(st.integers(1, 5), min_size=1, max_size=40),
    cut=st.integers(1, 40),
)
def test_the_median_interval_is_numpys_median_of_them_all(intervals: list[int], cut: int) -> None:
    stamps = np.concatenate([[0], np.cumsum(intervals)]).astype(np.int64)
    scan = _Scan()
    for begin in range(0, stamps.size, cut):
        part = stamps[begin : begin + cut]
        scan.add(part, np.zeros((part.size, 2)))
    assert scan.median_interval() == float(np.median(np.diff(stamps)))


def test_progress_is_reported_unless_quiet(bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["identify", str(bag), "--bootstrap", "20"]) == 0
    err = capsys.readouterr().err
    assert "reading excite" in err and f"preparing {bag}" in err and "estimating" in err
    assert main(["identify", str(bag), "--bootstrap", "20", "--quiet"]) == 0
    assert all(line.startswith("warning: ") for line in capsys.readouterr().err.splitlines())
