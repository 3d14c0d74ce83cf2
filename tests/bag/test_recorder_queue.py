"""recorder_node's queue depth: what bounds the middleware's memory of a stalled recorder (docs/BAGS.md)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from smm_bag.recorder_node import RecorderConfig


@pytest.mark.parametrize("depth", [0, -5, 1_000_001])
def test_a_queue_depth_out_of_range_is_refused_with_its_name(depth: int) -> None:
    with pytest.raises(ValueError, match="queue_depth"):
        RecorderConfig(queue_depth=depth)


@pytest.mark.ros
def test_every_subscription_queues_queue_depth_messages(ros_context: Any, tmp_path: Path) -> None:
    from smm_bag.recorder_node import RecorderNode

    topics = "/smm/joint_states,/smm/torque_command,/diagnostics"
    node = RecorderNode(
        context=ros_context,
        parameter_overrides={"output": str(tmp_path / "bag"), "topics": topics, "queue_depth": 123},
    )
    try:
        subscriptions = {topic: entry[0] for topic, entry in node._recorded.items()}
        assert sorted(subscriptions) == sorted(topics.split(","))  # known types: subscribed at start
        assert {topic: s.qos_profile.depth for topic, s in subscriptions.items()} == dict.fromkeys(
            subscriptions, 123
        )
    finally:
        node.destroy_node()
