"""Identification through the hardware path: smm-launch --plant hardware --scenario excite --record, identify.

Lockstep (the emulator clocked by the controller's answers) in ``make test``; real time at 1 kHz (bridge +
emulator) needs a quiet machine: ``make test-realtime`` (docs/IDENTIFICATION.md, docs/TESTING.md).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from launcher_run import smm_launch
from smm_analysis.identification import PARAMETER_NAMES, parameter_vector
from smm_analysis.runs.recorded import load_run

from smm_dynamics import SMMParameters

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def _record_excite(ros_processes: Any, bag: Path, clock_mode: str, *options: str) -> None:
    """``smm-launch --plant hardware --scenario excite --duration 12 --record bag``, ``options``; exit 0."""
    code, logs = smm_launch(
        ros_processes,
        "smm-launch-excite-hardware",
        *("--plant", "hardware", "--clock-mode", clock_mode, "--scenario", "excite", "--duration", "12"),
        *options,
        *("--record", str(bag)),
    )
    assert code == 0, logs
    assert "smm_bench_emulator completed its run" in logs


def _identify(bag: Path, out: Path) -> tuple[str, np.ndarray]:
    """``smm-bag identify bag --out out``: what it printed, the identified parameter vector."""
    identify = subprocess.run(
        [sys.executable, "-m", "smm_bag.cli", "identify", str(bag), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert identify.returncode == 0, identify.stderr
    model = yaml.safe_load((out / "model.yaml").read_text())["/**/controller_node"]["ros__parameters"][
        "model"
    ]
    fields: dict[str, Any] = {
        key: tuple(value) if isinstance(value, list) else value for key, value in model.items()
    }
    return identify.stdout, parameter_vector(SMMParameters(**fields))


TRUTH = parameter_vector(SMMParameters().with_inertia_scale(1.1))
"""The emulator's excite plant."""


@pytest.mark.parametrize("clock_mode", ["lockstep", pytest.param("realtime", marks=pytest.mark.realtime)])
def test_excite_on_the_emulator_is_identified_within_five_percent(
    ros_processes: Any, tmp_path: Path, clock_mode: str
) -> None:
    bag = tmp_path / "excite"
    _record_excite(ros_processes, bag, clock_mode)
    out = tmp_path / "model"
    _, estimate = _identify(bag, out)
    report = (out / "REPORT.md").read_text()
    assert "valve model" in report and "measured torque" in report
    applied = load_run(bag).applied_torque
    assert applied is not None
    largest = float(np.abs(applied).max())  # N m: the scale of the parameters whose truth is 0
    for name, found, true in zip(PARAMETER_NAMES, estimate, TRUTH, strict=True):
        tolerance = 0.05 * (abs(true) if true != 0.0 else largest)
        assert abs(found - true) <= tolerance, f"{name}: {found} vs {true}"


GAINS = {"valve_gain_positive": [0.8, 0.8], "valve_gain_negative": [1.2, 1.2]}
"""A bench whose valves give 0.8x the modelled torque driving q positive and 1.2x driving it negative."""


def test_a_valve_gain_per_direction_is_identified_apart_from_the_inertias(
    ros_processes: Any, tmp_path: Path
) -> None:
    """Issue 44: lockstep excite on a bench with known gains, the bridge's defaults; the measured torque."""
    bench = tmp_path / "bench.yaml"
    bench.write_text(yaml.safe_dump(GAINS), encoding="utf-8")
    bag = tmp_path / "excite"
    _record_excite(ros_processes, bag, "lockstep", "--bench-file", str(bench))
    printed, estimate = _identify(bag, tmp_path / "model")
    rows = [line.split("|") for line in printed.splitlines() if line.startswith(("| alpha |", "| beta |"))]
    assert len(rows) == 4, printed
    for row in rows:
        truth = GAINS[f"valve_gain_{row[2].strip()}"][0]
        low, high = (float(value) for value in row[4].strip(" []").split(","))
        assert abs(float(row[3]) / truth - 1.0) < 0.03, row
        assert low <= float(row[3]) <= high, row
    for name in ("I11", "I22", "I44", "I55"):
        index = PARAMETER_NAMES.index(name)
        assert abs(estimate[index] / TRUTH[index] - 1.0) < 0.05, (
            f"{name}: {estimate[index]} vs {TRUTH[index]}"
        )
