"""QoS profile of each topic, and why.

All topics are RELIABLE + VOLATILE + KEEP_LAST; only the depth differs.

* Control chain (``joint_states``, ``joint_states_filtered``, ``reference``, ``torque_command``,
  ``disturbance_estimate``): RELIABLE because in lockstep every node waits for the sample stamped with the
  current step, so a lost sample would stall the step, and on the bench a node must never act on a stream
  with holes. VOLATILE because a late joiner must not act on old measurements or commands. Depth 10 absorbs
  a burst (scheduling jitter of a few periods) without keeping stale commands queued for long: at 1 kHz the
  queue holds at most 10 ms.
* Diagnostics (``ground_truth``, ``observer_state``, ``controller_internals``): RELIABLE + depth 100 so that
  a recorder (rosbag2, plotjuggler) loses nothing at 1 kHz even when it stalls up to 100 ms on disk I/O;
  nothing in the loop reads them, so a deep queue costs the loop nothing.
* ``/clock``: RELIABLE depth 10 on the simulator's publisher. rclpy's own time source subscribes with
  BEST_EFFORT depth 1, which is compatible with a RELIABLE publisher; lockstep correctness never depends
  on /clock delivery because every message carries the stamp of the measurement it answers.

Publishers and subscriptions differ in depth on the control topics and /clock (docs/INTERFACES.md, QoS):
publishers keep 100 samples (100 ms at 1 kHz) so that a reader that stalls (a recorder writing to disk)
gets every sample re-sent instead of losing the ones the writer overwrote; the control nodes' own
subscriptions keep 10, so that a stalled node works through at most 10 ms of backlog, not 100 ms of stale
measurements or commands.
"""

from typing import Final

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from smm_msgs_py import topics

CONTROL_QOS_DEPTH: Final[int] = 10
"""Queue depth of the control nodes' subscriptions to control-chain topics (samples; 10 ms at 1 kHz)."""

PUBLISHER_QOS_DEPTH: Final[int] = 100
"""History depth of every publisher of the stack (samples; 100 ms at 1 kHz): what a slow reader can lag."""

DIAGNOSTIC_QOS_DEPTH: Final[int] = PUBLISHER_QOS_DEPTH
"""Queue depth of the diagnostic topics, publishers and subscriptions (samples; 100 ms at 1 kHz)."""

CLOCK_QOS_DEPTH: Final[int] = PUBLISHER_QOS_DEPTH
"""History depth of the /clock publisher (samples)."""

_SUBSCRIPTION_DEPTH_BY_TOPIC: Final[dict[str, int]] = {
    **{name: CONTROL_QOS_DEPTH for name in topics.CONTROL_TOPICS},
    **{name: DIAGNOSTIC_QOS_DEPTH for name in topics.DIAGNOSTIC_TOPICS},
    topics.CLOCK: CONTROL_QOS_DEPTH,
}


def _reliable_volatile(depth: int) -> QoSProfile:
    # rclpy's QoSProfile.__init__ is untyped (**kwargs) when rclpy is installed, Any when it is not.
    return QoSProfile(  # type: ignore[no-untyped-call,unused-ignore]
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


def control_qos() -> QoSProfile:
    """Return the subscription profile of the control-chain topics: RELIABLE, VOLATILE, KEEP_LAST depth 10.

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).
    """
    return _reliable_volatile(CONTROL_QOS_DEPTH)


def diagnostic_qos() -> QoSProfile:
    """Return the profile of the diagnostic topics: RELIABLE, VOLATILE, KEEP_LAST depth 100.

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).
    """
    return _reliable_volatile(DIAGNOSTIC_QOS_DEPTH)


def clock_qos() -> QoSProfile:
    """Return the profile of the /clock publisher: RELIABLE, VOLATILE, KEEP_LAST depth 100.

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).
    """
    return _reliable_volatile(CLOCK_QOS_DEPTH)


def qos_for_topic(topic: str) -> QoSProfile:
    """Return the publisher profile of a stack topic (:mod:`smm_msgs_py.topics`): RELIABLE, KEEP_LAST 100.

    Args:
        topic: The relative topic name (e.g. ``topics.TORQUE_COMMAND``) or ``topics.CLOCK``, as passed to
            ``create_publisher`` (before namespacing and remapping).

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).

    Raises:
        KeyError: ``topic`` is not a topic of the stack.
    """
    _check_topic(topic)
    return _reliable_volatile(PUBLISHER_QOS_DEPTH)


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
