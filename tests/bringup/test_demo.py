"""`make demo` (python -m smm_bringup.demo): the graph run's indices equal the offline loop's."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.ros


@pytest.mark.parametrize(("chain", "reference"), [("fused", "controller"), ("split", "node")])
def test_demo_runs_the_graph_and_matches_the_offline_loop(
    ros_processes: Any, tmp_path: Path, chain: str, reference: str
) -> None:
    out = tmp_path / "demo"
    demo = ros_processes.start(
        "demo",
        [
            sys.executable,
            "-m",
            "smm_bringup.demo",
            "--controllers",
            "fpdeso",
            "--duration",
            "0.3",
            "--out",
            str(out),
            "--chain",
            chain,
            "--reference",
            reference,
        ],
    )
    assert demo.popen.wait(timeout=180) == 0, demo.logs()
    document = json.loads((out / "metrics.json").read_text())
    assert (document["chain"], document["reference"]) == (chain, reference)
    run = document["runs"]["fpdeso"]
    assert run["steps"] == 300
    for joint in ("alpha", "beta"):
        graph, offline = run["graph"][joint], run["offline"][joint]
        assert graph["RMS"] > 0
        assert graph == pytest.approx(offline, rel=1e-9)
    assert (out / "fpdeso.npz").is_file()
