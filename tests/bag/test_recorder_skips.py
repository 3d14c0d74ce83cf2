"""recorder_node skips a topic whose message type is not installed: one warning, named in the manifest."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from smm_bag.errors import CorruptBagError
from smm_bag.manifest import RunManifest

from smm_bag import read_metadata

HIDDEN = "shape_msgs"
"""An installed interface package that nothing of the recorder imports: hidden from its process."""


def test_the_skipped_topics_survive_the_round_trip_and_only_when_there_are_some() -> None:
    manifest = RunManifest(scenario="case2", topics_skipped={"/extra": "shape_msgs/msg/Plane"})
    assert RunManifest.from_custom_data(manifest.to_custom_data()) == manifest
    assert "smm.topics_skipped" not in RunManifest().to_custom_data()


@pytest.mark.parametrize("text", ["[a, b]", "{/a: [1]}", "{unclosed"])
def test_a_malformed_list_of_skipped_topics_is_a_corrupt_manifest(text: str) -> None:
    data = RunManifest().to_custom_data() | {"smm.topics_skipped": text}
    with pytest.raises(CorruptBagError, match="run manifest"):
        RunManifest.from_custom_data(data)


@pytest.mark.ros
def test_a_topic_of_a_type_not_installed_is_skipped_with_a_warning_and_the_rest_recorded(
    ros_context: Any, ros_processes: Any, tmp_path: Path
) -> None:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from shape_msgs.msg import Plane
    from std_msgs.msg import String

    shadow = tmp_path / "shadow" / HIDDEN
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text(f"raise ImportError('{HIDDEN} is not installed here')\n")
    bag = tmp_path / "recorded"
    path = os.pathsep.join(filter(None, [str(shadow.parent), os.environ.get("PYTHONPATH", "")]))
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
            "topics:=/extra,/words",
        ],
        env={"PYTHONPATH": path},
    )
    node = rclpy.create_node("publisher", context=ros_context)
    planes = node.create_publisher(Plane, "/extra", 10)
    words = node.create_publisher(String, "/words", 10)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    deadline = time.monotonic() + 60.0
    while words.get_subscription_count() == 0 or "skipping /extra" not in recorder.logs():
        assert time.monotonic() < deadline and recorder.popen.poll() is None, recorder.logs()
        executor.spin_once(timeout_sec=0.05)
    sent = 0
    while sent < 5:
        planes.publish(Plane())
        words.publish(String(data=f"word {sent}"))
        sent += 1
    words.wait_for_all_acked(rclpy.duration.Duration(seconds=10))
    ros_processes.assert_all_alive()
    os.killpg(recorder.popen.pid, signal.SIGINT)
    assert recorder.popen.wait(timeout=30) == 0, recorder.logs()
    executor.shutdown()
    node.destroy_node()
    metadata = read_metadata(bag)
    assert {topic.name: topic.message_count for topic in metadata.topics} == {"/words": 5}
    manifest = RunManifest.from_custom_data(metadata.custom_data)
    assert manifest.topics_skipped == {"/extra": "shape_msgs/msg/Plane"}
    warned = [line for line in recorder.logs().splitlines() if "skipping /extra" in line]
    assert len(warned) == 1 and "shape_msgs/msg/Plane is not installed" in warned[0], recorder.logs()
    assert "1 topics skipped (type not installed): /extra" in recorder.logs()
