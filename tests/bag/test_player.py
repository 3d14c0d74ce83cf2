"""smm-bag play publishes every message of a bag, in order, with the recorded bytes, remapped and filtered."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
from bag.bag_helpers import T0, joint_state, torque
from smm_bag.player import PlayOptions, parse_remaps, play
from smm_bag.writer import BagWriter

from smm_bag import QosProfile

pytestmark = pytest.mark.ros


def _bag(path: Path, count: int) -> Path:
    with BagWriter(path) as writer:
        writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState", [QosProfile(depth=10)])
        writer.create_topic("/smm/torque_command", "std_msgs/msg/Float64MultiArray", [QosProfile(depth=10)])
        for k in range(count):
            writer.write("/smm/joint_states", joint_state(k), T0 + k * 1_000_000)
            writer.write("/smm/torque_command", torque(k), T0 + k * 1_000_000 + 1000)
    return path


def test_play_publishes_every_message_in_order(ros_context: Any, tmp_path: Path) -> None:
    import threading

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    bag = _bag(tmp_path / "bag", 300)
    listener = rclpy.create_node("listener", context=ros_context)
    received: list[bytes] = []
    commands: list[Any] = []
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    listener.create_subscription(JointState, "/replayed/joint_states", received.append, qos, raw=True)
    listener.create_subscription(Float64MultiArray, "/smm/torque_command", commands.append, qos)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(listener)
    done = threading.Event()

    def spin() -> None:
        while not done.is_set():
            executor.spin_once(timeout_sec=0.01)

    thread = threading.Thread(target=spin)
    thread.start()
    player = rclpy.create_node("player", context=ros_context)
    try:
        options = PlayOptions(
            rate=2.0,
            topics=("/smm/joint_states",),
            remaps=parse_remaps(["/smm/joint_states:=/replayed/joint_states"]),
            wait_for_subscribers_s=10.0,
        )
        result = play(bag, player, options)
        for publisher in player.publishers:
            publisher.wait_for_all_acked()
        deadline = time.monotonic() + 10
        while len(received) < 300 and time.monotonic() < deadline:
            time.sleep(0.02)
    finally:
        done.set()
        thread.join()
    assert result.published == {"/replayed/joint_states": 300}
    sent = [joint_state(k) for k in range(300)]
    assert [bytes(data)[: len(original)] for data, original in zip(received, sent, strict=True)] == sent
    assert all(len(data) - len(original) < 4 for data, original in zip(received, sent, strict=True))
    assert commands == []  # filtered out


def test_play_options_are_validated() -> None:
    for bad in ({"rate": 0.0}, {"start_offset_s": -1.0}, {"clock_period_s": 0.0}):
        with pytest.raises(ValueError):
            PlayOptions(**bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="/old:=/new"):
        parse_remaps(["joint_states:=/x"])


def test_topics_of_uninstalled_types_are_skipped_with_one_warning_and_the_rest_play(
    ros_context: Any, tmp_path: Path
) -> None:
    import rclpy
    from mcap.writer import Writer

    path = tmp_path / "foreign.mcap"  # a bare file, as `ros2 bag record` users pass them
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start("ros2", "tests")
        kinds = {
            "/smm/joint_states": ("sensor_msgs/msg/JointState", "cdr"),
            "/lidar": ("no_such_pkg/msg/Scan", "cdr"),
            "/status": ("std_msgs/msg/String", "json"),
        }
        channels = {}
        for topic, (kind, encoding) in kinds.items():
            schema = writer.register_schema(kind, "ros2msg", b"")
            channels[topic] = writer.register_channel(topic, encoding, schema)
        for k in range(50):
            for channel in channels.values():
                writer.add_message(channel, T0 + k * 1_000_000, joint_state(k), T0 + k * 1_000_000)
        writer.finish()  # type: ignore[no-untyped-call]
    warnings: list[str] = []
    player = rclpy.create_node("player", context=ros_context)
    result = play(path, player, PlayOptions(rate=50.0), warn=warnings.append)
    assert result.published == {"/smm/joint_states": 50}
    assert set(result.skipped) == {"/lidar", "/status"}
    assert len(warnings) == 2
    assert any("no_such_pkg/msg/Scan is not installed" in text for text in warnings)
    assert any("not CDR" in text for text in warnings)
