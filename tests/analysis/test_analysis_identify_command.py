"""smm-bag identify on real bags written from simulated runs: model.yaml, report, figures, bad bags."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml
from smm_analysis.closed_loop import Trajectory, run_closed_loop
from smm_analysis.identification import PARAMETER_NAMES, parameter_vector
from smm_analysis.identification.truth import draw_plant, simulate_excitation
from smm_analysis.identify_command import MODEL_NODES
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_analysis.scenarios import get_scenario
from smm_bag.cdr import encode_joint_state
from smm_bag.cli import main
from smm_bag.reader import BagReader
from smm_bag.writer import BagWriter
from smm_bringup.parameter_files import load_parameter_file
from smm_sim.plant import PlantConfig

from smm_dynamics import SMMParameters

PLANT = draw_plant(7)


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("identify")
    excite = simulate_excitation(PLANT, seed=7, noisy=False)
    sine = run_closed_loop(
        get_scenario("case1").with_duration(8.0),
        "fpdeso",
        plant_config=PlantConfig(params=PLANT),
        record_internals=False,
    )
    paths = {"excite": folder / "excite", "sine": folder / "sine"}
    write_trajectory_bag(excite, paths["excite"], internals=False)
    write_trajectory_bag(sine, paths["sine"], internals=False)
    paths["no_effort"] = _without_effort(excite, paths["excite"], folder / "no_effort")
    return paths


def _without_effort(run: Trajectory, bag: Path, target: Path) -> Path:
    """The same bag with joint_states carrying positions only (a plant that reports no effort)."""
    stamps = {int(stamp): index for index, stamp in enumerate(run.t_ns)}
    with BagReader(bag) as reader, BagWriter(target) as writer:
        for topic in reader.metadata.topics:
            writer.create_topic(topic.name, topic.type, topic.offered_qos_profiles)
        for key, value in reader.metadata.custom_data.items():
            writer.set_custom_data(key, value)
        order = iter(sorted(stamps))
        for message in reader.messages():
            data = message.data
            if message.topic.endswith("/joint_states"):
                stamp = next(order)
                data = encode_joint_state(
                    stamp, ["alpha", "beta"], run.measured_position[stamps[stamp]].tolist(), [], []
                )
            writer.write(message.topic, data, message.log_time_ns, message.publish_time_ns)
    return target


def test_identify_writes_the_model_the_report_and_figures(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    code = main(
        [
            "identify",
            str(bags["excite"]),
            "--validate",
            str(bags["sine"]),
            "--out",
            str(out),
            "--bootstrap",
            "40",
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert "| I11 |" in printed and "condition number" in printed and "NRMSE" in printed
    model = yaml.safe_load((out / "model.yaml").read_text())
    assert set(model) == set(MODEL_NODES)
    fields: dict[str, Any] = {
        key: tuple(value) if isinstance(value, list) else value
        for key, value in model["/**/controller_node"]["ros__parameters"]["model"].items()
    }
    identified = SMMParameters(**fields)
    truth, estimate = parameter_vector(PLANT), parameter_vector(identified)
    for name, true, found in zip(PARAMETER_NAMES, truth, estimate, strict=True):
        assert abs(found - true) <= 0.01 * abs(true), name
    report = (out / "REPORT.md").read_text()
    assert "| validation |" in report and "filtfilt" in report and "bootstrap" in report
    assert "valve model" in report
    figures = sorted(path.name for path in out.glob("*.png"))
    assert figures == [
        "excitation_identification1.png",
        "excitation_validation1.png",
        "torque_identification1.png",
        "torque_validation1.png",
    ]


def test_model_yaml_is_read_by_rcl_as_model_parameters(bags: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert main(["identify", str(bags["excite"]), "--out", str(out), "--no-plots", "--bootstrap", "20"]) == 0
    for node in ("/smm/controller_node", "/smm/fleso_node"):
        values = load_parameter_file(out / "model.yaml", node)
        assert set(values) == {f"model.{name}" for name in SMMParameters.__dataclass_fields__}
        assert all(isinstance(value, (float, list)) for value in values.values())


def test_a_bag_without_effort_exits_missing_topics_naming_it(
    bags: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(bags["no_effort"])]) == 6
    assert "effort" in capsys.readouterr().err


def test_a_run_that_moves_too_little_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    step = run_closed_loop(get_scenario("step").with_duration(1.0), "fpdeso", record_internals=False)
    write_trajectory_bag(step, tmp_path / "step", internals=False)
    assert main(["identify", str(tmp_path / "step")]) == 2
    assert "usable motion" in capsys.readouterr().err


def test_not_a_bag_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["identify", str(tmp_path / "nothing")]) == 3
    assert "error" in capsys.readouterr().err


def test_invalid_options_are_usage_errors(bags: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["identify", str(bags["excite"]), "--bootstrap", "3"]) == 2
    assert "bootstrap" in capsys.readouterr().err


def test_the_recorded_excitation_is_found_in_the_node_parameters() -> None:
    from smm_analysis.identify_command import recorded_excitation
    from smm_controller.excitation import ExcitationReference

    internal = {"/smm/controller_node": {"reference.kind": "excite", "reference.excite.period": 4.0}}
    assert recorded_excitation(internal) == ExcitationReference(period=4.0)
    node = {"/smm/reference_node": {"kind": "excite", "excite.start": [0.1, 0.0]}}
    assert recorded_excitation(node) == ExcitationReference(start=(0.1, 0.0))
    assert recorded_excitation({"/smm/reference_node": {"kind": "sine"}}) is None
    assert recorded_excitation({"/smm/reference_node": {"kind": "excite", "excite.harmonics": 1}}) is None
