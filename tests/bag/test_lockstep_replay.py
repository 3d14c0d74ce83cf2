"""smm-bag play --lockstep into a fresh fleso_node reproduces a recorded split-chain run's estimates."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

pytestmark = pytest.mark.ros

ESTIMATE = "/smm/disturbance_estimate"
INPUTS = ("/smm/joint_states_filtered", "/smm/joint_states", "/smm/torque_command")
STEPS = 200


def _first_per_stamp(bag: Path, topic: str) -> dict[int, bytes]:
    from smm_bag.cdr import stamp_of
    from smm_bag.reader import BagReader

    first: dict[int, bytes] = {}
    with BagReader(bag) as reader:
        kind = reader.topics[topic]
        for message in reader.messages([topic]):
            stamp = stamp_of(kind, message.data)
            assert stamp is not None
            first.setdefault(stamp, bytes(message.data))
    return first


def test_lockstep_replay_into_fleso_node_reproduces_the_recorded_estimates(
    ros_processes: Any, ros_context: Any, tmp_path: Path
) -> None:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from smm_bag.lockstep import LockstepOptions, play_lockstep
    from smm_bag.manifest import RunManifest
    from smm_bag.metadata import read_metadata

    bag = tmp_path / "split_run"
    launch = [sys.executable, "-m", "smm_bringup.launcher", "--chain", "split", "--reference", "node"]
    launch += ["--scenario", "case2", "--seed", "7", "--duration", str(STEPS / 1000), "--record", str(bag)]
    graph = ros_processes.start("graph", launch)
    assert graph.popen.wait(timeout=120) == 0, graph.logs()
    recorded = _first_per_stamp(bag, ESTIMATE)
    assert sorted(recorded) == [k * 1_000_000 for k in range(STEPS)]

    # A fresh fleso_node with the recorded node's parameters (from the bag's manifest).
    parameters = RunManifest.from_custom_data(read_metadata(bag).custom_data).parameters["/smm/fleso_node"]
    params_file = tmp_path / "fleso.yaml"
    params_file.write_text(yaml.safe_dump({"/smm/fleso_node": {"ros__parameters": parameters}}))
    fleso = ros_processes.start(
        "fleso_node",
        [
            sys.executable,
            "-m",
            "smm_controller.fleso_node",
            "--ros-args",
            "-r",
            "__ns:=/smm",
            "--params-file",
            str(params_file),
        ],
    )
    node = rclpy.create_node("lockstep_player", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    try:
        result = play_lockstep(
            bag, node, executor, LockstepOptions(answer_topic=ESTIMATE, topics=INPUTS, timeout_s=10.0)
        )
    finally:
        executor.shutdown()
        node.destroy_node()
    assert fleso.popen.poll() is None, fleso.logs()
    assert result.timeouts == (), fleso.logs()
    # Each (topic, stamp) once; the recording's re-published measurements are not played twice.
    assert result.published["/smm/joint_states_filtered"] == STEPS
    assert list(result.stamps[:STEPS]) == sorted(recorded)
    # Bit for bit: the replayed node's answer is the recorded message, byte for byte (stamp, layout, values).
    assert {stamp: result.answers[stamp] for stamp in recorded} == recorded


def test_lockstep_options_are_validated(tmp_path: Path) -> None:
    from smm_bag.cli import main
    from smm_bag.lockstep import LockstepOptions

    with pytest.raises(ValueError, match="absolute"):
        LockstepOptions(answer_topic="disturbance_estimate")
    with pytest.raises(ValueError, match="timeout"):
        LockstepOptions(answer_topic="/smm/disturbance_estimate", timeout_s=0.0)
    assert main(["play", str(tmp_path), "--lockstep", "relative"]) == 2
