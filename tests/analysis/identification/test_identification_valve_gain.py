"""smm-bag identify with the bridge's measured torque: valve gain per direction apart from the inertias."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml
from smm_analysis.closed_loop import Trajectory
from smm_analysis.errors import NotExcitingError
from smm_analysis.identification import PARAMETER_NAMES, parameter_vector
from smm_analysis.identification.truth import draw_plant, simulate_excitation
from smm_analysis.identification.valve_gain import GainSums, estimate_gain
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_bag.cdr import encode_float64_multi_array
from smm_bag.cli import main
from smm_bag.reader import BagReader
from smm_bag.writer import BagWriter

from smm_dynamics import SMMParameters

PLANT = draw_plant(7)
GAINS = np.array([[0.8, 1.2], [1.1, 0.9]])
"""The valve's true gain over the bridge's model: (alpha, beta) x (positive, negative torque)."""
NOISE = 0.04
"""Measured torque noise (N m): the emulator's A/D noise of 2 codes at 54.6 codes per N m."""
INERTIAS = ("I11", "I22", "I44", "I55")


def _modelled(true: np.ndarray) -> np.ndarray:
    """The bridge's valve model's torque for the valve's ``true`` torque: wrong by GAINS per direction."""
    gain = np.where(true >= 0.0, GAINS[:, 0], GAINS[:, 1])
    modelled: np.ndarray = true / gain
    return modelled


def _with_measured_torque(run: Trajectory, bag: Path, target: Path, rows: int | None = None) -> Path:
    """``bag`` plus ``hw_bridge_internals`` carrying ``measured_torque`` (the true torque, noisy) per step.

    ``rows``: only the first so many steps carry it.
    """
    generator = np.random.default_rng(3)
    measured = np.vstack([np.zeros((1, 2)), run.applied_torque[:-1]])
    measured = measured + generator.normal(0.0, NOISE, measured.shape)
    stamps = {int(stamp): index for index, stamp in enumerate(run.t_ns)}
    with BagReader(bag) as reader, BagWriter(target) as writer:
        joint_states = next(
            topic.name for topic in reader.metadata.topics if topic.name.endswith("joint_states")
        )
        internals = joint_states.replace("joint_states", "hw_bridge_internals")
        for topic in reader.metadata.topics:
            writer.create_topic(topic.name, topic.type, topic.offered_qos_profiles)
        writer.create_topic(internals, "std_msgs/msg/Float64MultiArray", [])
        for key, value in reader.metadata.custom_data.items():
            writer.set_custom_data(key, value)
        order = iter(sorted(stamps))
        for message in reader.messages():
            writer.write(message.topic, message.data, message.log_time_ns, message.publish_time_ns)
            if message.topic != joint_states:
                continue
            stamp = next(order)
            k = stamps[stamp]
            if rows is not None and k >= rows:
                continue
            dims = (
                ("quantity:measured_torque", 1, 2),
                ("joint:alpha,beta", 2, 2),
                (f"stamp_ns:{stamp}", 1, 1),
            )
            data = measured[k].tolist()
            writer.write(internals, encode_float64_multi_array(dims, data), message.log_time_ns + 300_000)
    return target


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("valve_gain")
    excite = simulate_excitation(PLANT, seed=7, noisy=False)
    modelled = dataclasses.replace(excite, applied_torque=_modelled(excite.applied_torque))
    write_trajectory_bag(modelled, folder / "effort_only", internals=False)
    return {
        "effort_only": folder / "effort_only",
        "measured": _with_measured_torque(excite, folder / "effort_only", folder / "measured"),
        "partial": _with_measured_torque(excite, folder / "effort_only", folder / "partial", rows=5000),
    }


def _identified(out: Path) -> SMMParameters:
    model = yaml.safe_load((out / "model.yaml").read_text())["/**/controller_node"]["ros__parameters"][
        "model"
    ]
    return SMMParameters(
        **{key: tuple(value) if isinstance(value, list) else value for key, value in model.items()}
    )


def _inertia_errors(params: SMMParameters) -> list[float]:
    truth, found = parameter_vector(PLANT), parameter_vector(params)
    return [
        abs(found[PARAMETER_NAMES.index(name)] / truth[PARAMETER_NAMES.index(name)] - 1.0)
        for name in INERTIAS
    ]


def test_the_measured_torque_gives_the_gain_per_direction_within_3_percent_and_the_inertias_within_5(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert (
        main(["identify", str(bags["measured"]), "--out", str(out), "--bootstrap", "40", "--no-plots"]) == 0
    )
    printed = capsys.readouterr().out
    assert "valve gain (measured / modelled torque)" in printed
    rows = [line.split("|") for line in printed.splitlines() if line.startswith(("| alpha |", "| beta |"))]
    assert len(rows) == 4
    for row in rows:
        joint, direction = row[1].strip(), row[2].strip()
        truth = GAINS[("alpha", "beta").index(joint), ("positive", "negative").index(direction)]
        ratio = float(row[3])
        low, high = (float(value) for value in row[4].strip(" []").split(","))
        assert abs(ratio / truth - 1.0) < 0.03, (joint, direction, ratio)
        assert low <= ratio <= high
    assert max(_inertia_errors(_identified(out))) < 0.05
    report = (out / "REPORT.md").read_text()
    assert "## Valve gain per direction" in report and "measured torque" in report


def test_without_the_measured_torque_the_valve_gain_scales_the_inertias(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert (
        main(["identify", str(bags["effort_only"]), "--out", str(out), "--bootstrap", "40", "--no-plots"])
        == 0
    )
    assert "valve gain" not in capsys.readouterr().out
    assert max(_inertia_errors(_identified(out))) > 0.05  # what the measured torque corrects


def test_a_bag_with_the_measured_torque_at_some_steps_only_uses_the_effort_and_says_so(
    bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["identify", str(bags["partial"]), "--bootstrap", "40"]) == 0
    captured = capsys.readouterr()
    assert "valve gain" not in captured.out
    assert "measured torque (hw_bridge.measured_torque) is missing at" in captured.err


def test_a_direction_never_driven_is_refused_by_name() -> None:
    sums = GainSums(1.0, np.array([1.0, 1.0]))
    time = np.arange(1000) * 1e-3
    model = np.column_stack([np.sin(time * 20.0), np.abs(np.sin(time * 20.0))])  # beta never negative
    sums.add(time, 1.1 * model, model)
    with pytest.raises(NotExcitingError, match="beta negative"):
        estimate_gain([sums], 20, 0)
