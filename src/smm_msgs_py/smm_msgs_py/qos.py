"""QoS profile of each topic (why: docs/INTERFACES.md, "Depths and durability").

RELIABLE + KEEP_LAST everywhere; deep TRANSIENT_LOCAL publishers, shallow VOLATILE subscriptions.
"""

from typing import Final

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from smm_msgs_py import topics

CONTROL_QOS_DEPTH: Final[int] = 10
"""Queue depth of the control nodes' subscriptions to control-chain topics (samples; 10 ms at 1 kHz)."""

PUBLISHER_QOS_DEPTH: Final[int] = 1000
"""History depth of every publisher of the stack (samples; 1 s at 1 kHz): how far a slow reader may lag."""

DIAGNOSTIC_QOS_DEPTH: Final[int] = 100
"""Queue depth of the subscriptions to the diagnostic topics (samples; 100 ms at 1 kHz)."""

CLOCK_QOS_DEPTH: Final[int] = PUBLISHER_QOS_DEPTH
"""History depth of the /clock publisher (samples)."""

_SUBSCRIPTION_DEPTH_BY_TOPIC: Final[dict[str, int]] = {
    **{name: CONTROL_QOS_DEPTH for name in topics.CONTROL_TOPICS},
    **{name: DIAGNOSTIC_QOS_DEPTH for name in topics.DIAGNOSTIC_TOPICS},
    topics.CLOCK: CONTROL_QOS_DEPTH,
}


def _reliable_volatile(depth: int, durability: DurabilityPolicy = DurabilityPolicy.VOLATILE) -> QoSProfile:
    # rclpy's QoSProfile.__init__ is untyped (**kwargs) when rclpy is installed, Any when it is not.
    return QoSProfile(  # type: ignore[no-untyped-call,unused-ignore]
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=durability,
    )


def _publisher(depth: int = 0) -> QoSProfile:
    return _reliable_volatile(depth or PUBLISHER_QOS_DEPTH, DurabilityPolicy.TRANSIENT_LOCAL)


def control_qos() -> QoSProfile:
    """Return the subscription profile of the control-chain topics: RELIABLE, VOLATILE, KEEP_LAST depth 10.

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).
    """
    return _reliable_volatile(CONTROL_QOS_DEPTH)


def diagnostic_qos() -> QoSProfile:
    """Return the profile of a diagnostic publisher (``~/internals``, ``/diagnostics``): KEEP_LAST 1000.

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).
    """
    return _publisher()


def clock_qos() -> QoSProfile:
    """Return the profile of the /clock publisher: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST depth 1000.

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).
    """
    return _publisher(CLOCK_QOS_DEPTH)


def qos_for_topic(topic: str) -> QoSProfile:
    """Return the publisher profile of a stack topic: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1000.

    Args:
        topic: The relative topic name (e.g. ``topics.TORQUE_COMMAND``) or ``topics.CLOCK``, as passed to
            ``create_publisher`` (before namespacing and remapping).

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).

    Raises:
        KeyError: ``topic`` is not a topic of the stack.
    """
    _check_topic(topic)
    return _publisher()


def subscription_qos_for_topic(topic: str) -> QoSProfile:
    """Return the profile a node of the loop subscribes a topic with (control topics and /clock: depth 10).

    Args:
        topic: The relative topic name or ``topics.CLOCK``, as passed to ``create_subscription``.

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).

    Raises:
        KeyError: ``topic`` is not a topic of the stack.
    """
    _check_topic(topic)
    return _reliable_volatile(_SUBSCRIPTION_DEPTH_BY_TOPIC[topic])


def _check_topic(topic: str) -> None:
    if topic not in _SUBSCRIPTION_DEPTH_BY_TOPIC:
        raise KeyError(f"unknown topic {topic!r}; known topics: {', '.join(topics.ALL_TOPICS)}")
