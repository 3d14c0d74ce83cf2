"""`make demo` (python -m smm_bringup.demo): the graph run's indices equal the offline loop's."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.ros


STEPS = 1000
"""1 s at 1 kHz: the plant lives long enough for the recorder to read its parameters into the manifest."""


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
            str(STEPS / 1000),
            "--out",
            str(out),
            "--bags",
            str(tmp_path / "bags"),
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
    assert run["steps"] == STEPS and run["missing_steps"] == 0  # every commanded step is in the bag
    # Nothing lost, per topic: every stamp the simulator stepped (its own count, from its statistics file) is
    # in the bag on every stepped topic. The simulator re-publishes a measurement until it is answered, so
    # distinct stamps, not messages, are compared with its step count.
    stepped = ["joint_states", "ground_truth", "reference", "torque_command"]
    if chain == "split":
        stepped += ["joint_states_filtered", "disturbance_estimate"]
    expected = {f"/smm/{topic}": STEPS for topic in stepped} | {"/clock": STEPS}
    assert run["simulator_steps"] == STEPS
    assert run["recorded_stamps"] == expected
    # Every message the simulator published, re-publications included, is in the bag.
    assert set(run["published"]) == {"/smm/joint_states", "/smm/ground_truth", "/clock"}
    assert run["published"]["/smm/joint_states"] >= STEPS
    assert run["recorded_messages"] == run["published"]
    for joint in ("alpha", "beta"):
        graph, offline = run["graph"][joint], run["offline"][joint]
        assert graph["RMS"] > 0
        assert graph == pytest.approx(offline, rel=1e-9)
    bag = Path(run["bag"])
    assert bag.parent == tmp_path / "bags" and (bag / "metadata.yaml").is_file()
    from smm_analysis.runs.recorded import stamps_per_topic

    stamps = stamps_per_topic(bag)
    assert set(stamps) == set(expected)  # no stepped topic is left out of the count
    assert all({k * 1_000_000 for k in range(STEPS)} <= stamps[topic] for topic in expected)
    assert not list(out.glob("*.npz"))  # the simulator's side channel is gone
    assert (out / "analysis" / "REPORT.md").is_file() and (out / "analysis" / "tracking.png").is_file()
    from smm_bag.manifest import RunManifest
    from smm_bag.metadata import read_metadata

    manifest = RunManifest.from_custom_data(read_metadata(bag).custom_data)
    assert (manifest.scenario, manifest.controller, manifest.plant) == ("case2", "fpdeso", "sim")
    assert manifest.parameters["/smm/controller_node"]["algorithm"] == "fpdeso"  # every node's parameters
    # The simulator of a 1 s run may end before the recorder reads it (a loaded machine): then it is named.
    assert "/smm/smm_sim_node" in manifest.parameters or "/smm/smm_sim_node" in manifest.parameters_unread
    analysed = json.loads((out / "analysis" / "metrics.json").read_text())["case2"]["fpdeso"]
    for joint in ("alpha", "beta"):
        assert analysed[joint]["RMS"] == pytest.approx(run["graph"][joint]["RMS"], rel=1e-12)
