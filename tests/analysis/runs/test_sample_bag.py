"""The committed sample bag (a real recorder_node recording of the graph) reads, analyses, re-runs.

The bag was recorded on another machine, so every comparison of numbers computed here with numbers in
it is within :data:`smm_analysis.runs.agreement.CROSS_MACHINE` (docs/BAGS.md, "Rerun across machines");
these tests are marked ``cross_machine`` and run under other numeric paths by ``make test-other-cpu`` and by
``test_other_numeric_paths.py`` (docs/TESTING.md, "Floats across machines").
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from bag.bag_helpers import mcap_messages, rewrite_bag, rosbags_messages
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.metrics import joint_indices
from smm_analysis.runs.agreement import CROSS_MACHINE, judge
from smm_analysis.runs.indices import evaluate
from smm_analysis.runs.recorded import load_run
from smm_analysis.runs.rerun import chain_settings, rerun
from smm_analysis.scenarios import get_scenario
from smm_bag.cdr import decode_float64_multi_array, encode_float64_multi_array
from smm_bag.cli import main
from smm_bag.exit_codes import EXIT_CHECK_FAILED, EXIT_OK
from smm_bag.reader import BagMessage

from smm_bag import read_metadata

SAMPLE = Path(__file__).resolve().parents[3] / "bags" / "sample_case2_fpdeso"
SHIFT_ULPS = 3

pytestmark = pytest.mark.cross_machine


def test_both_readers_agree_with_the_metadata() -> None:
    counts = {topic.name: topic.message_count for topic in read_metadata(SAMPLE).topics}
    assert {topic: len(messages) for topic, messages in rosbags_messages(SAMPLE).items()} == counts
    assert {topic: len(messages) for topic, messages in mcap_messages(SAMPLE).items()} == counts


def test_the_graph_recording_equals_the_offline_loop_within_the_cross_machine_tolerance() -> None:
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
    # In the closed loop a sign flip would move the plant, so the next steps would differ too (not isolated);
    # rounding makes one as rarely as in a re-run, and the failure would name the step.
    agreement = judge(
        run.t_ns,
        offline.command_torque[:steps],
        run.command_torque,
        flip_size=chain_settings({}, "fpdeso").flip_size,
        tolerance=CROSS_MACHINE,
    )
    assert agreement.ok, agreement.failures
    expected = joint_indices(
        offline.t_ns[:steps],
        offline.desired_position[:steps],
        offline.position[:steps],
        offline.command_torque[:steps],
    )
    recorded = evaluate(run)
    for joint in ("alpha", "beta"):
        for name in ("Ma", "Ave", "RMS", "eps_u", "du_rms"):
            assert getattr(recorded.joints[joint], name) == pytest.approx(
                getattr(expected[joint], name), rel=CROSS_MACHINE.index_relative
            )


def test_rerun_reproduces_the_recorded_commands_and_estimates_within_the_cross_machine_tolerance() -> None:
    run = load_run(SAMPLE)
    settings = chain_settings({}, "fpdeso")
    result = rerun(run, settings)
    assert result.recorded_estimate is not None
    agreement = judge(
        result.t_ns,
        result.command,
        result.recorded_command,
        flip_size=settings.flip_size,
        tolerance=CROSS_MACHINE,
        estimate=result.estimate,
        recorded_estimate=result.recorded_estimate,
    )
    assert agreement.ok, agreement.failures
    assert agreement.estimate_max_difference is not None
    assert max(agreement.estimate_max_difference) <= CROSS_MACHINE.relative * float(
        np.max(np.abs(result.recorded_estimate))
    )


def _shift_recorded_values(topics: frozenset[str], ulps: int) -> Callable[[BagMessage], bytes]:
    """A ``rewrite_bag`` change: every value of ``topics`` moved ``ulps`` units in the last place up."""

    def change(message: BagMessage) -> bytes:
        if message.topic not in topics:
            return message.data
        decoded = decode_float64_multi_array(message.data)
        values = np.array(decoded.data)
        for _ in range(ulps):
            values = np.nextafter(values, np.inf)
        return encode_float64_multi_array(decoded.dims, values.tolist(), decoded.data_offset)

    return change


def test_a_copy_a_few_ulp_off_passes_the_default_and_fails_bit_for_bit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = load_run(SAMPLE).manifest
    recorded_topics = frozenset({manifest.topic("torque_command"), manifest.topic("disturbance_estimate")})
    shifted = tmp_path / "shifted"
    rewrite_bag(SAMPLE, shifted, _shift_recorded_values(recorded_topics, SHIFT_ULPS))
    original, moved = load_run(SAMPLE), load_run(shifted)
    assert np.all(moved.command_torque != original.command_torque)
    np.testing.assert_array_equal(moved.measured_position, original.measured_position)
    capsys.readouterr()

    assert main(["rerun", str(shifted), "--expect-equal", "--json"]) == EXIT_OK
    default = json.loads(capsys.readouterr().out)
    assert default["reproduces_recording"] is True and default["sign_flips"] == [0, 0]
    assert max(default["command_max_abs_difference_Nm"]) > 0.0

    assert main(["rerun", str(shifted), "--expect-equal", "--tolerance", "0", "--json"]) == EXIT_CHECK_FAILED
    captured = capsys.readouterr()
    exact = json.loads(captured.out)
    assert exact["reproduces_recording"] is False
    assert exact["command_max_abs_difference_Nm"] == default["command_max_abs_difference_Nm"]
    assert "does not reproduce the recording (commands differ by up to" in captured.err
