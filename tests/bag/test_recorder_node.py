"""recorder_node in its own process: every published message is in the bag after SIGINT or SIGTERM."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag.bag_helpers import mcap_messages, rosbags_messages
from smm_bag.cdr import stamp_of
from smm_bag.loss import loss_from_json

from smm_bag import BagReader, read_metadata

pytestmark = pytest.mark.ros

COUNT = 1500
PERIOD_S = 0.002
ACK_BLOCK = 250


def _publish(context: Any, count: int) -> None:
    import rclpy
    from rclpy.duration import Duration
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from smm_msgs_py.conversions import JointSample, clock_msg, sample_to_joint_state, torque_to_msg
    from smm_msgs_py.qos import qos_for_topic
    from std_msgs.msg import Float64MultiArray

    node = rclpy.create_node("publisher", context=context)
    joint_states = node.create_publisher(JointState, "/smm/joint_states", qos_for_topic("joint_states"))
    commands = node.create_publisher(
        Float64MultiArray, "/smm/torque_command", qos_for_topic("torque_command")
    )
    clock = node.create_publisher(Clock, "/clock", qos_for_topic("/clock"))
    deadline = time.monotonic() + 20.0
    while (
        time.monotonic() < deadline
        and min(p.get_subscription_count() for p in (joint_states, commands, clock)) == 0
    ):
        time.sleep(0.05)
    time.sleep(0.5)  # let the reliable endpoints match both ways
    start = time.monotonic()
    for k in range(count):
        stamp = (k + 1) * 1_000_000
        clock.publish(clock_msg(stamp))
        sample = JointSample(
            stamp_ns=stamp, position=np.array([k * 1e-3, -k * 1e-3]), effort=np.array([1.0, 2.0])
        )
        joint_states.publish(sample_to_joint_state(sample))
        commands.publish(torque_to_msg(np.array([float(k), 0.5]), stamp))
        # 500 Hz; every ACK_BLOCK samples the publishers wait until the recorder has acknowledged them, so a
        # recorder stalled by a busy machine never lets the history (depth 1000) overwrite an unread sample:
        # what the test checks is the finish, not the machine's speed (1 kHz figures: bench/bench_bag.py).
        if (k + 1) % ACK_BLOCK == 0:
            for publisher in (joint_states, commands, clock):
                assert publisher.wait_for_all_acked(Duration(seconds=60))
        pause = start + (k + 1) * PERIOD_S - time.monotonic()
        if pause > 0:
            time.sleep(pause)

    for publisher in (joint_states, commands, clock):  # delivered (acknowledged) before the stop signal
        assert publisher.wait_for_all_acked(Duration(seconds=10))
    node.destroy_node()


@pytest.mark.parametrize("stop_signal", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_clean_finish_loses_nothing(
    ros_context: Any, ros_processes: Any, tmp_path: Path, stop_signal: signal.Signals
) -> None:
    bag = tmp_path / "recorded"
    recorder = ros_processes.start(
        "recorder",
        [
            sys.executable,
            "-m",
            "smm_bag.recorder_node",
            "--ros-args",
            "-p",
            f"output:={bag}",
            "-p",
            "topics:=/smm/joint_states,/smm/torque_command,/clock",
            "-p",
            "scenario:=case2",
            "-p",
            "plant:=sim",
        ],
    )
    _publish(ros_context, COUNT)
    ros_processes.assert_all_alive()

    os.killpg(recorder.popen.pid, stop_signal)
    assert recorder.popen.wait(timeout=30) == 0, recorder.logs()
    metadata = read_metadata(bag)
    counts = {topic.name: topic.message_count for topic in metadata.topics}
    assert counts == {"/smm/joint_states": COUNT, "/smm/torque_command": COUNT, "/clock": COUNT}, (
        recorder.logs()
    )
    loss = loss_from_json(metadata.custom_data["smm.loss"])
    assert all(entry["lost"] == 0 for entry in loss.values())
    assert loss["/smm/joint_states"]["stamp_gaps"] == 0 and loss["/smm/joint_states"]["received"] == COUNT
    assert metadata.custom_data["smm.scenario"] == "case2" and metadata.custom_data["smm.plant"] == "sim"
    by_rosbags = rosbags_messages(bag)
    # Log time is DDS's reception time of each sample: a reliable retransmission arrives after later samples
    # and ties share one datagram's time, so log-time order is not publication order; by stamp, nothing is
    # lost, doubled or changed.
    stamp_ns_of = lambda m: m.header.stamp.sec * 10**9 + m.header.stamp.nanosec  # noqa: E731
    samples = sorted(by_rosbags["/smm/joint_states"], key=lambda s: stamp_ns_of(s[1]))
    assert [m.position[0] for _, m in samples] == [k * 1e-3 for k in range(COUNT)]
    assert [len(v) for v in mcap_messages(bag).values()] == [COUNT] * 3
    qos = metadata.topic("/smm/joint_states")
    assert qos is not None and qos.offered_qos_profiles[0].reliability == "reliable"
    assert qos.offered_qos_profiles[0].depth == 1000  # the stack's publisher depth
    with BagReader(bag) as reader:
        times = [m.log_time_ns for m in reader.messages(["/smm/joint_states"])]
    assert times == sorted(times) and times[0] > 1_600_000_000 * 10**9


def test_the_manifest_names_the_nodes_whose_parameters_it_could_not_read(
    ros_context: Any, ros_processes: Any, tmp_path: Path
) -> None:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from smm_bag.manifest import RunManifest

    bag = tmp_path / "recorded"
    recorder = ros_processes.start(
        "recorder",
        [sys.executable, "-m", "smm_bag.recorder_node", "--ros-args", "-p", f"output:={bag}"],
    )
    shown = rclpy.create_node("shown", namespace="/smm", context=ros_context)
    shown.declare_parameter("gain", 2.5)
    # A node that never answers for its parameters, as one that ends before the recorder asks it.
    silent = rclpy.create_node(
        "silent", namespace="/smm", context=ros_context, start_parameter_services=False
    )
    executor = SingleThreadedExecutor(context=ros_context)
    for node in (shown, silent):
        executor.add_node(node)
    deadline = time.monotonic() + 60.0
    while silent.count_clients("/smm/silent/list_parameters") == 0:  # the recorder saw it and waits for it
        assert time.monotonic() < deadline, recorder.logs()
        executor.spin_once(timeout_sec=0.05)
    os.killpg(recorder.popen.pid, signal.SIGINT)
    while recorder.popen.poll() is None and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    assert recorder.popen.wait(timeout=30) == 0, recorder.logs()
    executor.shutdown()
    for node in (shown, silent):
        node.destroy_node()
    manifest = RunManifest.from_custom_data(read_metadata(bag).custom_data)
    assert "/smm/silent" in manifest.parameters_unread and "/smm/silent" not in manifest.parameters
    assert ("/smm/shown" in manifest.parameters) != ("/smm/shown" in manifest.parameters_unread)
    if "/smm/shown" in manifest.parameters:
        assert manifest.parameters["/smm/shown"]["gain"] == 2.5
    warned = [line for line in recorder.logs().splitlines() if "the manifest has no parameters of" in line]
    assert len(warned) == 1 and "/smm/silent" in warned[0]


def test_sigkill_then_repair_recovers_everything_flushed(
    ros_context: Any, ros_processes: Any, tmp_path: Path
) -> None:
    from smm_bag.repair import repair_bag

    bag = tmp_path / "killed"
    recorder = ros_processes.start(
        "recorder",
        [
            sys.executable,
            "-m",
            "smm_bag.recorder_node",
            "--ros-args",
            "-p",
            f"output:={bag}",
            "-p",
            "topics:=/smm/joint_states,/smm/torque_command,/clock",
            "-p",
            "flush_interval:=0.2",
        ],
    )
    _publish(ros_context, COUNT)
    time.sleep(1.0)  # longer than the flush interval: the recorder's timer flushed without new messages
    os.killpg(recorder.popen.pid, signal.SIGKILL)
    recorder.popen.wait(timeout=30)
    assert (bag / "metadata.yaml").is_file()  # written at open
    report = repair_bag(bag)
    assert report.changed
    counts = {topic.name: topic.message_count for topic in report.metadata.topics}
    assert counts == {"/smm/joint_states": COUNT, "/smm/torque_command": COUNT, "/clock": COUNT}
    assert [len(v) for v in rosbags_messages(bag).values()] == [COUNT] * 3
    assert [len(v) for v in mcap_messages(bag).values()] == [COUNT] * 3


@pytest.mark.parametrize(
    ("split", "value"), [("max_size", "65536"), ("max_duration", "1.0")], ids=["by-size", "by-duration"]
)
def test_split_recording_keeps_every_message_the_manifest_and_the_counts_in_every_file(
    ros_context: Any, ros_processes: Any, tmp_path: Path, split: str, value: str
) -> None:
    bag = tmp_path / "split"
    topics = ("/smm/joint_states", "/smm/torque_command", "/clock")
    recorder = ros_processes.start(
        "recorder",
        [
            sys.executable, "-m", "smm_bag.recorder_node", "--ros-args",
            "-p", f"output:={bag}", "-p", f"topics:={','.join(topics)}",
            "-p", "scenario:=case2", "-p", "plant:=sim", "-p", f"{split}:={value}",
        ],
    )  # fmt: skip
    _publish(ros_context, COUNT)
    os.killpg(recorder.popen.pid, signal.SIGINT)
    assert recorder.popen.wait(timeout=30) == 0, recorder.logs()

    metadata = read_metadata(bag)
    files = metadata.files
    assert len(files) >= 2, recorder.logs()  # 1500 x 3 messages: > 64 KiB and > 1 s at 500 Hz
    assert [info.path for info in files] == [f"split_{index}.mcap" for index in range(len(files))]
    assert sum(info.message_count for info in files) == metadata.message_count == 3 * COUNT
    assert {topic.name: topic.message_count for topic in metadata.topics} == dict.fromkeys(topics, COUNT)
    loss = loss_from_json(metadata.custom_data["smm.loss"])
    assert all(entry["lost"] == 0 and entry["stamp_missing"] == 0 for entry in loss.values())
    if split == "max_duration":
        # The writer starts a new file at the first message 1 s or more after the file's first one.
        assert all(info.duration_ns < 1_000_000_000 for info in files[:-1])
    stamps: list[int] = []
    for info in files:
        with BagReader(bag / info.path) as part:  # each file alone: its counts and the run manifest
            assert part.message_count == info.message_count
            assert part.metadata.custom_data["smm.scenario"] == "case2"
            assert part.metadata.custom_data["smm.plant"] == "sim"
            stamps += [
                stamp_of(type_name, data)
                for _, _, data in part.raw_messages(["/smm/joint_states"])
                for type_name in [part.topics["/smm/joint_states"]]
            ]
    # In stored order, file after file: no sample lost, repeated or reordered at a split.
    assert stamps == [(k + 1) * 1_000_000 for k in range(COUNT)]
