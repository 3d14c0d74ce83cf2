"""``smm-bag rerun`` streamed equals the in-memory re-run (``load_run`` + ``rerun`` + ``judge``) on real bags,
across block boundaries, and its memory does not grow with the bag's length."""

from __future__ import annotations

import itertools
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from bag.bag_helpers import rewrite_bag
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.runs.agreement import (
    CROSS_MACHINE,
    AgreementAccumulator,
    Tolerance,
    allowed_difference,
    judge,
)
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_analysis.runs.recorded import load_run
from smm_analysis.runs.rerun import ChainSettings, chain_settings, rerun
from smm_analysis.runs.rerun_stream import RerunCsv, RerunSummary, rerun_stream, survey
from smm_analysis.runs.stream import StepStream
from smm_analysis.scenarios import get_scenario
from smm_bag.cdr import decode_joint_state, encode_joint_state
from smm_bag.cli import main
from smm_bag.reader import BagMessage

BLOCK = 97
"""Steps per block in these tests: many blocks, none a divisor of the run."""
SAMPLE = Path(__file__).resolve().parents[3] / "bags" / "sample_case2_fpdeso"
CHANGED_GAINS = {"fpdeso.fuzzy.kp0": [3000.0, 3000.0]}


@pytest.fixture(scope="module")
def case2_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    trajectory = run_closed_loop(get_scenario("case2").with_duration(1.2), "fpdeso", seed=4)
    bag = tmp_path_factory.mktemp("rerun") / "case2"
    write_trajectory_bag(trajectory, bag)
    return bag


def _without_effort_from(step: int) -> Callable[[BagMessage], bytes]:
    """A ``rewrite_bag`` change: ``joint_states`` from the ``step``-th message on without effort."""
    seen = {"count": 0}

    def change(message: BagMessage) -> bytes:
        if not message.topic.endswith("/joint_states"):
            return message.data
        seen["count"] += 1
        if seen["count"] <= step:
            return message.data
        state = decode_joint_state(message.data)
        return encode_joint_state(state.stamp_ns, state.name, state.position, state.velocity, ())

    return change


def _streamed(bag: Path, settings: ChainSettings, tolerance: Tolerance, csv: Path) -> RerunSummary:
    found = survey(StepStream(bag, block_steps=BLOCK, read_batch=300))
    with RerunCsv(csv, recorded_estimate=found.estimate_complete) as rows:
        return rerun_stream(
            StepStream(bag, block_steps=BLOCK, read_batch=300), settings, found, tolerance, rows
        )


def _in_memory_csv(path: Path, columns: list[np.ndarray], header: list[str]) -> None:
    """``rerun.csv`` as ``smm-bag rerun`` wrote it from whole arrays before it streamed."""
    np.savetxt(path, np.hstack(columns), delimiter=",", header=",".join(header), comments="", fmt="%.17g")


@pytest.mark.parametrize(
    ("case", "gains", "tolerance"),
    [
        ("recorded gains, bit for bit", {}, Tolerance(0.0, 0.0, 0.0)),
        ("recorded gains", {}, CROSS_MACHINE),
        ("other gains", CHANGED_GAINS, CROSS_MACHINE),
        ("no effort after step 1000", {}, CROSS_MACHINE),
    ],
)
def test_streamed_rerun_equals_the_in_memory_rerun(
    case2_bag: Path, tmp_path: Path, case: str, gains: dict[str, object], tolerance: Tolerance
) -> None:
    bag = case2_bag
    if case.startswith("no effort"):
        bag = tmp_path / "partial_effort"
        rewrite_bag(case2_bag, bag, _without_effort_from(1000))
    run = load_run(bag)
    settings = chain_settings(gains, "fpdeso")
    memory = rerun(run, settings)
    assert memory.recorded_estimate is not None
    verdict = judge(
        memory.t_ns,
        memory.command,
        memory.recorded_command,
        flip_size=settings.flip_size,
        tolerance=tolerance,
        estimate=memory.estimate,
        recorded_estimate=memory.recorded_estimate,
    )
    streamed = _streamed(bag, settings, tolerance, tmp_path / "rerun.csv")
    assert streamed.steps == memory.t_ns.size > 10 * BLOCK
    assert streamed.applied_source == memory.applied_source
    assert (memory.applied_source == "recorded effort") == (not case.startswith("no effort"))
    # the summary as rerun computed it from whole arrays: max, RMS (numpy's step-order sum), exact
    difference = np.abs(memory.command - memory.recorded_command)
    assert streamed.agreement.command_max_difference == tuple(difference.max(axis=0).tolist())
    assert streamed.command_rms_offline == tuple(np.sqrt(np.mean(memory.command**2, axis=0)).tolist())
    assert streamed.command_rms_recorded == tuple(
        np.sqrt(np.mean(memory.recorded_command**2, axis=0)).tolist()
    )
    estimate = np.abs(memory.estimate - memory.recorded_estimate).max(axis=0)
    assert streamed.agreement.estimate_max_difference == tuple(estimate.tolist())
    for field in ("command_allowed", "estimate_allowed", "flip_steps", "flip_counts", "outside_counts"):
        assert getattr(streamed.agreement, field) == getattr(verdict, field), field
    assert streamed.agreement.first_outside == verdict.first_outside
    assert streamed.agreement.ok == verdict.ok == (not gains)
    # the indices summed in numpy's order: the same bits
    assert streamed.agreement.index_relative_difference == verdict.index_relative_difference
    assert (streamed.agreement.index_relative_difference == 0.0) == (not gains)
    expected = tmp_path / "in_memory.csv"
    names = ["command_offline", "command_recorded", "estimate_offline", "estimate_recorded"]
    _in_memory_csv(
        expected,
        [
            memory.t_ns.astype(np.float64).reshape(-1, 1),
            memory.command,
            memory.recorded_command,
            memory.estimate,
            memory.recorded_estimate,
        ],
        ["t_ns", *(f"{name}_{joint}" for name in names for joint in ("alpha", "beta"))],
    )
    assert (tmp_path / "rerun.csv").read_bytes() == expected.read_bytes()
    assert not (tmp_path / "rerun.csv.partial").exists()


def test_the_sample_bag_streamed_equals_in_memory_in_every_printed_field(tmp_path: Path) -> None:
    settings = chain_settings({}, "fpdeso")
    run = load_run(SAMPLE)
    memory = rerun(run, settings)
    verdict = judge(
        memory.t_ns,
        memory.command,
        memory.recorded_command,
        flip_size=settings.flip_size,
        tolerance=CROSS_MACHINE,
        estimate=memory.estimate,
        recorded_estimate=memory.recorded_estimate,
    )
    streamed = _streamed(SAMPLE, settings, CROSS_MACHINE, tmp_path / "rerun.csv").agreement
    assert streamed == verdict  # a bag from another machine: differences of a few ULP, judged the same


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.integers(1, 399), max_size=6, unique=True),
    st.lists(st.integers(0, 399), min_size=1, max_size=30, unique=True),
    st.lists(st.integers(0, 399), max_size=5, unique=True),
)
def test_blocks_judge_as_the_whole_arrays(cuts: list[int], flipped: list[int], outside: list[int]) -> None:
    t_ns = np.arange(400, dtype=np.int64) * 1_000_000
    recorded = np.column_stack([np.sin(t_ns / 1e8) * 3.0, np.cos(t_ns / 7e7) * 2.0])
    flip = chain_settings({}, "fpdeso").flip_size
    offline = recorded.copy()
    offline[flipped, 0] += flip[0] / 2.0  # flips, isolated or not
    offline[outside, 1] += 1.0  # steps beyond any flip
    whole = judge(t_ns, offline, recorded, flip_size=flip, tolerance=CROSS_MACHINE)
    accumulator = AgreementAccumulator(
        steps=400,
        command_allowed=allowed_difference(np.max(np.abs(recorded), axis=0), CROSS_MACHINE),
        flip_size=flip,
        tolerance=CROSS_MACHINE,
    )
    edges = [0, *sorted(cuts), 400]
    for start, end in itertools.pairwise(edges):
        accumulator.add(t_ns[start:end], offline[start:end], recorded[start:end])
    blocks = accumulator.result()
    for field in ("flip_steps", "flip_counts", "outside_counts", "first_outside", "command_max_difference"):
        assert getattr(blocks, field) == getattr(whole, field), field
    assert blocks == whole


def _peak_bytes(call: Callable[[], object]) -> int:
    tracemalloc.start()
    try:
        call()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_memory_does_not_grow_with_the_bags_length(tmp_path: Path) -> None:
    """Peak traced memory of the streamed rerun on a 1.5 s and a 4.5 s bag (blocks of 128 steps; both longer
    than the reorder window, which holds 1 s of samples)."""
    bags = {}
    for seconds in (1.5, 4.5):
        trajectory = run_closed_loop(get_scenario("case2").with_duration(seconds), "fpdeso", seed=0)
        bags[seconds] = tmp_path / f"case2_{seconds:g}"
        write_trajectory_bag(trajectory, bags[seconds], internals=False)
    settings = chain_settings({}, "fpdeso")

    def streamed(bag: Path) -> Callable[[], object]:
        def call() -> object:
            found = survey(StepStream(bag, block_steps=128, read_batch=512))
            with RerunCsv(tmp_path / "rerun.csv", recorded_estimate=found.estimate_complete) as rows:
                return rerun_stream(
                    StepStream(bag, block_steps=128, read_batch=512), settings, found, CROSS_MACHINE, rows
                )

        return call

    def in_memory(bag: Path) -> Callable[[], object]:
        return lambda: load_run(bag)  # what the re-run held before it streamed

    short, long = (_peak_bytes(streamed(bags[s])) for s in (1.5, 4.5))
    assert long <= 1.25 * short, (short, long)
    # the same measurement sees the in-memory run grow with the length
    memory_short, memory_long = (_peak_bytes(in_memory(bags[s])) for s in (1.5, 4.5))
    assert memory_long >= 2.0 * memory_short, (memory_short, memory_long)


def test_progress_of_both_passes_unless_quiet(case2_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["rerun", str(case2_bag)]) == 0
    err = capsys.readouterr().err
    assert "reading case2: 100 %" in err and "re-running case2: 100 %" in err
    assert main(["rerun", str(case2_bag), "--quiet"]) == 0
    assert capsys.readouterr().err == ""
