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
"""

from typing import Final

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from smm_msgs_py import topics

CONTROL_QOS_DEPTH: Final[int] = 10
"""Queue depth of the control-chain topics (samples; 10 ms at 1 kHz)."""

DIAGNOSTIC_QOS_DEPTH: Final[int] = 100
"""Queue depth of the diagnostic topics (samples; 100 ms at 1 kHz)."""

CLOCK_QOS_DEPTH: Final[int] = 10
"""Queue depth of the /clock publisher (samples)."""

_DEPTH_BY_TOPIC: Final[dict[str, int]] = {
    **{name: CONTROL_QOS_DEPTH for name in topics.CONTROL_TOPICS},
    **{name: DIAGNOSTIC_QOS_DEPTH for name in topics.DIAGNOSTIC_TOPICS},
    topics.CLOCK: CLOCK_QOS_DEPTH,
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
    """Return the profile of the control-chain topics: RELIABLE, VOLATILE, KEEP_LAST depth 10.

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
    """Return the profile of the /clock publisher: RELIABLE, VOLATILE, KEEP_LAST depth 10.

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).
    """
    return _reliable_volatile(CLOCK_QOS_DEPTH)


def qos_for_topic(topic: str) -> QoSProfile:
    """Return the QoS profile of a topic of :mod:`smm_msgs_py.topics`.

    Args:
        topic: The relative topic name (e.g. ``topics.TORQUE_COMMAND``) or ``topics.CLOCK``, as passed to
            ``create_publisher`` / ``create_subscription`` (before namespacing and remapping).

    Returns:
        A new profile (profiles are mutable, so each caller gets its own).

    Raises:
        KeyError: ``topic`` is not a topic of the stack.
    """
    try:
        depth = _DEPTH_BY_TOPIC[topic]
    except KeyError:
        raise KeyError(f"unknown topic {topic!r}; known topics: {', '.join(topics.ALL_TOPICS)}") from None
    return _reliable_volatile(depth)
