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
from smm_analysis.identification import PARAMETER_NAMES, parameter_vector
from smm_analysis.runs.recorded import load_run

from smm_dynamics import SMMParameters

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.mark.parametrize("clock_mode", ["lockstep", pytest.param("realtime", marks=pytest.mark.realtime)])
def test_excite_on_the_emulator_is_identified_within_five_percent(
    ros_processes: Any, tmp_path: Path, clock_mode: str
) -> None:
    bag = tmp_path / "excite"
    launcher = ros_processes.start(
        "smm-launch-excite-hardware",
        [
            sys.executable,
            "-m",
            "smm_bringup.launcher",
            "--plant",
            "hardware",
            "--clock-mode",
            clock_mode,
            "--scenario",
            "excite",
            "--duration",
            "12",
            "--record",
            str(bag),
        ],
    )
    try:
        code = launcher.popen.wait(timeout=600)
    except subprocess.TimeoutExpired:
        pytest.fail(f"smm-launch did not finish\n{launcher.logs()}")
    assert code == 0, launcher.logs()
    assert "smm_bench_emulator completed its run" in launcher.logs()
    out = tmp_path / "model"
    identify = subprocess.run(
        [sys.executable, "-m", "smm_bag.cli", "identify", str(bag), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert identify.returncode == 0, identify.stderr
    report = (out / "REPORT.md").read_text()
    assert "valve model" in report
    model = yaml.safe_load((out / "model.yaml").read_text())["/**/controller_node"]["ros__parameters"][
        "model"
    ]
    fields: dict[str, Any] = {
        key: tuple(value) if isinstance(value, list) else value for key, value in model.items()
    }
    estimate = parameter_vector(SMMParameters(**fields))
    truth = parameter_vector(SMMParameters().with_inertia_scale(1.1))  # the emulator's excite plant
    applied = load_run(bag).applied_torque
    assert applied is not None
    largest = float(np.abs(applied).max())  # N m: the scale of the parameters whose truth is 0
    for name, found, true in zip(PARAMETER_NAMES, estimate, truth, strict=True):
        tolerance = 0.05 * (abs(true) if true != 0.0 else largest)
        assert abs(found - true) <= tolerance, f"{name}: {found} vs {true}"
