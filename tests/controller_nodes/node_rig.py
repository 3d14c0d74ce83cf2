"""In-process rig for node tests: the nodes under test and a probe node in one private context.

The probe publishes the inputs and records every output; everything spins in one executor (the one the
stack uses, :func:`smm_node_runtime.make_executor`), so a test is a sequence of "publish, spin until
the answer arrived, check".
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from ros_harness import spin_until
from smm_msgs_py.conversions import JointSample, sample_to_joint_state
from smm_msgs_py.qos import qos_for_topic

from smm_msgs_py import topics

TIMEOUT_S = 10.0
QUIET_S = 0.3
"""How long a test spins to make sure that nothing (more) arrives (s)."""


class Rig:
    """Nodes under test plus a probe node, one executor."""

    def __init__(self, context: Any, nodes: Sequence[Any]) -> None:
        import rclpy

        from smm_node_runtime import make_executor

        self.context = context
        self.nodes = list(nodes)
        self.probe = rclpy.create_node("probe", context=context)
        self.executor = make_executor(context)
        for node in [*self.nodes, self.probe]:
            self.executor.add_node(node)
        self._publishers: dict[str, Any] = {}
        self.received: dict[str, list[Any]] = {}

    def publisher(self, topic: str) -> Any:
        """The probe's publisher on ``topic`` (created once; waits until a node subscribes)."""
        if topic not in self._publishers:
            pub = self.probe.create_publisher(topics.TOPIC_TYPES[topic], topic, qos_for_topic(topic))
            self._publishers[topic] = pub
            assert self.spin_until(lambda: pub.get_subscription_count() > 0), f"nobody subscribes {topic}"
        return self._publishers[topic]

    def record(self, topic: str, msg_type: type | None = None, qos: Any = None) -> list[Any]:
        """Record every message on ``topic``; waits until the publishing node is matched."""
        if topic not in self.received:
            messages: list[Any] = []
            msg_type = msg_type or topics.TOPIC_TYPES[topic]
            sub = self.probe.create_subscription(
                msg_type, topic, messages.append, qos if qos is not None else qos_for_topic(topic)
            )
            self.received[topic] = messages
            assert self.spin_until(lambda: sub.get_publisher_count() > 0), f"nobody publishes {topic}"
        return self.received[topic]

    def publish(self, topic: str, msg: Any) -> None:
        """Publish ``msg`` on ``topic`` from the probe."""
        self.publisher(topic).publish(msg)

    def spin_until(self, predicate: Callable[[], bool], timeout_s: float = TIMEOUT_S) -> bool:
        """Spin until ``predicate()`` holds or ``timeout_s`` passes."""
        return spin_until(self.executor, predicate, timeout_s)

    def wait_for(self, topic: str, count: int, timeout_s: float = TIMEOUT_S) -> list[Any]:
        """Spin until ``count`` messages were recorded on ``topic``; fail otherwise."""
        messages = self.received[topic]
        assert self.spin_until(lambda: len(messages) >= count, timeout_s), (
            f"{topic}: {len(messages)} of {count} messages after {timeout_s} s"
        )
        return messages

    def settle(self, seconds: float = QUIET_S) -> None:
        """Spin for ``seconds`` (to check that nothing else arrives)."""
        spin_until(self.executor, lambda: False, seconds)

    def close(self) -> None:
        """Stop spinning and destroy every node."""
        self.executor.shutdown()
        for node in [self.probe, *self.nodes]:
            node.destroy_node()


def measurement(
    stamp_ns: int,
    position: Sequence[float] = (0.1, -0.2),
    effort: Sequence[float] | None = (0.5, -0.25),
) -> Any:
    """A raw joint_states message (position rad, effort N m or None for none) stamped ``stamp_ns``."""
    applied = None if effort is None else np.array(effort)
    return sample_to_joint_state(JointSample(stamp_ns, np.array(position), None, applied))


def filtered(
    stamp_ns: int, position: Sequence[float] = (0.1, -0.2), velocity: Sequence[float] = (0.3, 0.4)
) -> Any:
    """A joint_states_filtered message (position rad, velocity rad/s) stamped ``stamp_ns``."""
    return sample_to_joint_state(JointSample(stamp_ns, np.array(position), np.array(velocity)))
