"""End to end: a sweep's run, re-run alone (``--rerun``), gives the sweep's indices, and its parameters file
runs on the real graph (smm-launch --clock-mode lockstep --params-file) and gives that run."""

from __future__ import annotations

import io
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from smm_analysis.batch import run_scalar
from smm_analysis.sweep.command import EXIT_OK, SweepOptions, rerun, sweep
from smm_analysis.sweep.spec import parse_spec

pytestmark = pytest.mark.ros

SPEC: dict[str, Any] = {
    "name": "e2e",
    "controller": "fpdeso",
    "scenarios": ["step"],
    "duration": 0.4,
    "fixed": {"fpdeso.boundary_layer": [0.05, 0.05]},
    "gains": {"fpdeso.fuzzy.kd0[1]": {"grid": [95.0, 111.0]}, "td.filter_factor": {"grid": [0.001, 0.002]}},
    "objectives": ["overshoot_beta", "rise_time_beta"],
    "select": "overshoot_beta",
}


def test_the_chosen_parameters_file_runs_on_the_graph_and_reproduces_the_sweeps_run(
    ros_processes: Any, tmp_path: Path
) -> None:
    spec_path = tmp_path / "spec.yaml"
    spec_path.write_text(yaml.safe_dump(SPEC), encoding="utf-8")
    out = tmp_path / "sweep"
    assert sweep(SweepOptions(spec_path, out, 1, None, None), io.StringIO(), io.StringIO()) == 0
    chosen = int(
        next(
            line for line in (out / "report.md").read_text().splitlines() if line.startswith("Gain set ")
        ).split()[2]
    )
    # One gain set, one plant draw and one scenario per run: the chosen set's run id is the set's index.
    assert rerun(SweepOptions(spec_path, out, 1, None, chosen), io.StringIO(), io.StringIO()) == EXIT_OK
    assert (out / "chosen.yaml").read_text().split("\n", 1)[1] == (
        out / f"rerun-{chosen}.yaml"
    ).read_text().split("\n", 1)[1]
    record = tmp_path / "record.npz"
    extra = tmp_path / "record.yaml"
    extra.write_text(f'/**/smm_sim_node:\n  ros__parameters:\n    record_file: "{record}"\n')
    launcher = ros_processes.start(
        "smm-launch-sweep",
        [
            sys.executable,
            "-m",
            "smm_bringup.launcher",
            "--clock-mode",
            "lockstep",
            "--scenario",
            "step",
            "--duration",
            "0.4",
            "--seed",
            "0",
            "--params-file",
            str(out / f"rerun-{chosen}.yaml"),
            "--params-file",
            str(extra),
        ],
    )
    code = int(launcher.popen.wait(timeout=150))
    assert code == 0, launcher.logs()
    offline = run_scalar(parse_spec(SPEC).settings(chosen))
    graph = np.load(record)
    np.testing.assert_array_equal(graph["stamp_ns"], offline.t_ns)
    np.testing.assert_allclose(graph["position"], offline.position, rtol=0, atol=1e-9)
    steps = graph["command"].shape[0]
    np.testing.assert_allclose(graph["command"], offline.command_torque[:steps], rtol=0, atol=1e-6)
