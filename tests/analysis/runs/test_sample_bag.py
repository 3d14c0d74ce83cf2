"""The committed sample bag (a real recorder_node recording of the graph) reads, analyses, re-runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag.bag_helpers import mcap_messages, rosbags_messages
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.metrics import joint_indices
from smm_analysis.runs.indices import evaluate
from smm_analysis.runs.recorded import load_run
from smm_analysis.runs.rerun import chain_settings, rerun
from smm_analysis.scenarios import get_scenario

from smm_bag import read_metadata

SAMPLE = Path(__file__).resolve().parents[3] / "bags" / "sample_case2_fpdeso"


def test_both_readers_agree_with_the_metadata() -> None:
    counts = {topic.name: topic.message_count for topic in read_metadata(SAMPLE).topics}
    assert {topic: len(messages) for topic, messages in rosbags_messages(SAMPLE).items()} == counts
    assert {topic: len(messages) for topic, messages in mcap_messages(SAMPLE).items()} == counts


def test_indices_equal_the_offline_loop_and_rerun_reproduces_the_commands() -> None:
    run = load_run(SAMPLE)
    manifest = run.manifest
    assert (manifest.scenario, manifest.controller, manifest.seed, manifest.plant) == (
        "case2",
        "fpdeso",
        1,
        "sim",
    )
    offline = run_closed_loop(get_scenario("case2").with_duration(2.0), "fpdeso", seed=1)
    steps = offline.t_ns.size - 1  # the last measurement is never answered
    assert run.incomplete_steps == 0 and run.t_ns.size == steps
    np.testing.assert_array_equal(run.t_ns, offline.t_ns[:steps])
    expected = joint_indices(
        offline.t_ns[:steps],
        offline.desired_position[:steps],
        offline.position[:steps],
        offline.command_torque[:steps],
    )
    recorded = evaluate(run)
    for joint in ("alpha", "beta"):
        for name in ("Ma", "Ave", "RMS", "eps_u"):
            assert getattr(recorded.joints[joint], name) == pytest.approx(
                getattr(expected[joint], name), rel=1e-9
            )
    result = rerun(run, chain_settings({}, "fpdeso"))
    assert result.max_command_difference == 0.0
    assert result.recorded_estimate is not None
    np.testing.assert_array_equal(result.estimate, result.recorded_estimate)
