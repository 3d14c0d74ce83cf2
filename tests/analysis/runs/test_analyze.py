"""smm-bag analyze and rerun on bags of known runs: the indices equal smm-reproduce's for the same run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from bag.bag_helpers import rewrite_bag
from smm_analysis.closed_loop import Trajectory, run_closed_loop
from smm_analysis.reproduction.reproduce import evaluate_run
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_analysis.runs.indices import evaluate
from smm_analysis.runs.plots import PLOTS
from smm_analysis.runs.recorded import load_run
from smm_analysis.scenarios import get_scenario
from smm_bag.cli import main
from smm_bag.exit_codes import EXIT_CHECK_FAILED
from smm_controller.laws import PAPER_LAWS

JOINTS = ("alpha", "beta")


@pytest.fixture(scope="module")
def case2_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Trajectory, Path]]:
    scenario = get_scenario("case2").with_duration(1.5)
    runs = {}
    for controller in PAPER_LAWS[:2]:
        trajectory = run_closed_loop(scenario, controller, seed=3)
        bag = tmp_path_factory.mktemp("bags") / controller
        write_trajectory_bag(trajectory, bag)
        runs[controller] = (trajectory, bag)
    return runs


def test_indices_equal_the_offline_evaluation(case2_runs: dict[str, tuple[Trajectory, Path]]) -> None:
    scenario = get_scenario("case2").with_duration(1.5)
    for trajectory, bag in case2_runs.values():
        run = load_run(bag)
        assert run.position_source == "ground truth"
        assert run.t_ns.size == trajectory.t_ns.size and run.incomplete_steps == 0
        recorded, offline = evaluate(run), evaluate_run(trajectory, scenario)
        for joint in JOINTS:
            for name in ("Ma", "Ave", "RMS", "eps_u", "du_rms"):
                assert getattr(recorded.joints[joint], name) == pytest.approx(
                    getattr(offline.joints[joint], name), rel=1e-12, abs=1e-15
                )
        for axis in ("x", "y", "z"):
            assert recorded.end_effector[axis].rms_mm == pytest.approx(
                offline.end_effector[axis].rms_mm, rel=1e-12
            )
        assert recorded.step is None
        np.testing.assert_array_equal(run.disturbance_estimate, trajectory.disturbance_estimate)


def test_step_metrics_on_a_step_bag(tmp_path: Path) -> None:
    scenario = get_scenario("step").with_duration(0.6)
    trajectory = run_closed_loop(scenario, "fpdeso", seed=0)
    write_trajectory_bag(trajectory, tmp_path / "step")
    recorded, offline = evaluate(load_run(tmp_path / "step")), evaluate_run(trajectory, scenario)
    assert recorded.step is not None and offline.step is not None
    for joint in JOINTS:
        assert recorded.step[joint] == offline.step[joint]


def test_measured_position_is_used_and_labelled_without_ground_truth(tmp_path: Path) -> None:
    scenario = get_scenario("case2").with_duration(0.3)
    trajectory = run_closed_loop(scenario, "fpd", seed=1)
    bag = tmp_path / "bench"
    write_trajectory_bag(trajectory, bag)
    # A bench bag: drop the ground truth from the metadata and files by rewriting without that topic.
    stripped = tmp_path / "stripped"
    rewrite_bag(bag, stripped, lambda message: None if message.topic == "/smm/ground_truth" else message.data)
    run = load_run(stripped)
    assert run.position_source == "measured"
    np.testing.assert_array_equal(run.position, trajectory.measured_position)
    error = trajectory.desired_position - trajectory.measured_position
    assert evaluate(run).joints["alpha"].Ma == pytest.approx(float(np.max(np.abs(error[:, 0]))), rel=1e-15)


def test_cli_json_table_report_and_plots(
    case2_runs: dict[str, tuple[Trajectory, Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bags = [str(bag) for _, bag in case2_runs.values()]
    assert main(["analyze", "--json", *bags]) == 0
    document = json.loads(capsys.readouterr().out)
    assert set(document) == {"case2", "meta"}
    assert set(document["case2"]) == set(PAPER_LAWS[:2])
    for controller in PAPER_LAWS[:2]:
        assert set(document["case2"][controller]) == {"alpha", "beta", "end_effector"}
        assert set(document["case2"][controller]["alpha"]) == {"Ma", "Ave", "RMS", "eps_u", "du_rms"}
    assert document["meta"]["bags"][bags[0]]["position_source"] == "ground truth"
    out = tmp_path / "report"
    assert main(["analyze", "--quiet", "--out", str(out), *bags]) == 0
    table = capsys.readouterr().out
    assert "| index | fpdeso (ground truth) | fpd (ground truth) |" in table
    assert "| alpha RMS (rad) |" in table
    report = (out / "REPORT.md").read_text()
    assert json.loads((out / "metrics.json").read_text())["case2"]["fpd"] == document["case2"]["fpd"]
    for name in PLOTS:
        assert (out / f"{name}.png").stat().st_size > 1000, name
        assert f"({name}.png)" in report


def test_rerun_with_recorded_gains_reproduces_the_commands(
    case2_runs: dict[str, tuple[Trajectory, Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trajectory, bag = case2_runs["fpdeso"]
    out = tmp_path / "rerun"
    # recorded and re-run in this test run: bit for bit (--tolerance 0), the claim rerun makes on one machine
    assert main(["rerun", str(bag), "--expect-equal", "--tolerance", "0", "--json", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["command_max_abs_difference_Nm"] == [0.0, 0.0]
    assert summary["estimate_max_abs_difference_Nm"] == [0.0, 0.0]
    table = np.loadtxt(out / "rerun.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table[:, 1:3], trajectory.command_torque)
    params = tmp_path / "gains.yaml"
    params.write_text(
        "/**/controller_node:\n  ros__parameters:\n    fpdeso:\n      fuzzy:\n        kp0: [3000.0, 3000.0]\n"
    )
    assert main(["rerun", str(bag), "--params-file", str(params), "--expect-equal"]) == EXIT_CHECK_FAILED
    assert "not isolated sign flips" in capsys.readouterr().err
    assert main(["rerun", str(bag), "--params-file", str(params)]) == 0
    changed = capsys.readouterr().out
    assert "command_max_abs_difference_Nm: [0.0, 0.0]" not in changed


def test_info_prints_ros2_bag_info_layout(
    case2_runs: dict[str, tuple[Trajectory, Path]], capsys: pytest.CaptureFixture[str]
) -> None:
    _, bag = case2_runs["fpd"]
    assert main(["info", str(bag)]) == 0
    text = capsys.readouterr().out
    assert "Files:             fpd_0.mcap" in text
    assert "Storage id:        mcap" in text and "ROS Distro:        jazzy" in text
    assert "Messages:          7505" in text
    assert (
        "Topic information: Topic: /smm/joint_states | Type: sensor_msgs/msg/JointState | Count: 1501 | "
        "Serialization Format: cdr" in text
    )
    assert "smm.scenario: case2" in text and "/smm/torque_command: 1501 / 1501 / 0" in text
