"""runs.segments and ``analyze --segments``: three experiments in one recording are three segments, each with
the indices of its window analysed alone."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from bag.bag_helpers import gain_event
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_analysis.runs.indices import evaluate_stream
from smm_analysis.runs.segments import find_segments
from smm_analysis.runs.stream import StepStream
from smm_analysis.scenarios import get_scenario
from smm_bag.cli import main
from smm_controller.chain import make_law

from smm_controller import FPDESOConfig
from smm_dynamics import SMMParameters

S = 1_000_000_000


@pytest.fixture(scope="module")
def three_experiments(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Case 1 (1.5 s), the same with other gains (1.5 s), case 2 (1.5 s): one bag, two parameter events."""
    case1, case2 = get_scenario("case1").with_duration(1.5), get_scenario("case2").with_duration(1.5)
    first = run_closed_loop(case1, "fpdeso", seed=1)
    retuned = run_closed_loop(
        case1, "fpdeso", seed=1, controller=make_law(FPDESOConfig(robust_gain=(1.0, 1.0)), SMMParameters())
    )
    second = run_closed_loop(case2, "fpdeso", seed=2)
    period = round(first.control_period * S)
    change = int(first.t_ns[-1] - first.t_ns[0]) + period  # first step of the second run
    scenario = 2 * change
    bag = tmp_path_factory.mktemp("segments") / "day"
    write_trajectory_bag(
        first,
        bag,
        then=(retuned, second),
        parameter_events=[
            (0, gain_event(0, name="use_sim_time")),  # ignored: not a gain
            (change, gain_event(change)),
            (scenario, gain_event(scenario, node="/smm/reference_node", name="scenario")),
        ],
    )
    return bag


def test_three_experiments_are_three_segments(three_experiments: Path) -> None:
    search = find_segments(three_experiments)
    assert [segment.steps for segment in search.segments] == [1501, 1501, 1501]
    assert search.short_segments == 0 and search.disarmed_steps == 0
    reasons = [segment.reason for segment in search.segments]
    assert reasons[0] == "start of the bag"
    assert "controller_node: fpdeso.robust_gain changed" in reasons[1]
    assert "reference_node: scenario changed" in reasons[2]
    ends = [segment.end_ns for segment in search.segments]
    assert ends[:2] == [search.segments[1].start_ns, search.segments[2].start_ns] and ends[2] is None


def test_each_segment_has_the_indices_of_its_window_analysed_alone(
    tmp_path: Path, three_experiments: Path
) -> None:
    out = tmp_path / "out"
    assert main(["analyze", str(three_experiments), "--segments", "--json", "--out", str(out)]) == 0
    document = json.loads((out / "metrics.json").read_text())
    bags = document["meta"]["bags"]
    assert len(bags) == 3
    for segment, (name, entry) in zip(find_segments(three_experiments).segments, bags.items(), strict=True):
        assert entry["window"] == segment.window.describe() and entry["steps"] == segment.steps
        alone = evaluate_stream(StepStream(three_experiments, window=segment.window))
        indices = document[entry["scenario"]][entry["controller"]]
        for joint in ("alpha", "beta"):
            for index in ("Ma", "Ave", "RMS", "eps_u", "du_rms"):
                assert indices[joint][index] == getattr(alone.joints[joint], index), (name, joint, index)
        # The window as a user types it: --start @a --end @b.
        start_end = segment.window.describe().split()
        windowed = tmp_path / f"alone{segment.number}"
        assert (
            main(
                [
                    "analyze",
                    str(three_experiments),
                    "--json",
                    "--no-plots",
                    "--out",
                    str(windowed),
                    *start_end,
                ]
            )
            == 0
        )
        alone_document = json.loads((windowed / "metrics.json").read_text())
        (alone_entry,) = alone_document["meta"]["bags"].values()
        assert alone_entry["steps"] == segment.steps
    assert sorted(path.name for path in out.glob("*.png"))  # figures drawn for the segments side by side


def test_segments_with_a_window_is_a_usage_error(
    three_experiments: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as raised:
        main(["analyze", str(three_experiments), "--segments", "--start", "1"])
    assert raised.value.code == 2
    assert "--segments finds its own windows" in capsys.readouterr().err


def test_rerun_of_each_segment_equals_the_rerun_of_its_window(
    tmp_path: Path, three_experiments: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "segments"
    assert main(["rerun", str(three_experiments), "--segments", "--json", "--out", str(out)]) == 0
    summaries = json.loads(capsys.readouterr().out)
    segments = find_segments(three_experiments).segments
    assert [summary["steps"] for summary in summaries] == [segment.steps for segment in segments]
    for segment, summary in zip(segments, summaries, strict=True):
        assert summary.pop("segment") == f"{segment.number} ({segment.reason})"
        windowed = tmp_path / f"alone{segment.number}"
        start_end = segment.window.describe().split()
        assert main(["rerun", str(three_experiments), "--json", "--out", str(windowed), *start_end]) == 0
        assert json.loads(capsys.readouterr().out) == summary
        alone = (windowed / "rerun.csv").read_bytes()
        assert (out / f"rerun_segment_{segment.number}.csv").read_bytes() == alone
    # each experiment re-runs with the gains in force at its start (the manifest's, then the gain change)
    assert [summary["reproduces_recording"] for summary in summaries[:2]] == [True, True]
    assert summaries[1]["command_max_abs_difference_Nm"] == [0.0, 0.0]
    with pytest.raises(SystemExit) as raised:
        main(["rerun", str(three_experiments), "--segments", "--start", "1"])
    assert raised.value.code == 2
