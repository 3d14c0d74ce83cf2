"""Topic names of the SMM stack.

Names are relative (no leading slash) so that nodes started under a namespace resolve them inside it:
under ``/smm`` (:data:`DEFAULT_NAMESPACE`) ``joint_states`` becomes ``/smm/joint_states``, and a launch file
can still remap each one. ``/clock`` is global because ROS time sources subscribe to it by absolute name.
"""

from collections.abc import Mapping
from types import MappingProxyType
from typing import Final

from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

DEFAULT_NAMESPACE: Final[str] = "smm"

JOINT_STATES: Final[str] = "joint_states"
"""Raw measurement, ``sensor_msgs/JointState``: position (rad), effort = applied torque (N m)."""

JOINT_STATES_FILTERED: Final[str] = "joint_states_filtered"
"""Tracking-differentiator output, ``sensor_msgs/JointState``: position (rad), velocity (rad/s)."""

GROUND_TRUTH: Final[str] = "ground_truth"
"""Simulator ground truth, ``sensor_msgs/JointState``: true position, velocity, effort = applied torque."""

REFERENCE: Final[str] = "reference"
"""Reference, ``std_msgs/Float64MultiArray`` 3x2 (rows position/velocity/acceleration)."""

TORQUE_COMMAND: Final[str] = "torque_command"
"""Torque command, ``std_msgs/Float64MultiArray`` [tau_alpha, tau_beta] (N m)."""

DISTURBANCE_ESTIMATE: Final[str] = "disturbance_estimate"
"""Disturbance estimate, labelled ``std_msgs/Float64MultiArray`` (row ``xi_tilde``, N m)."""

OBSERVER_STATE: Final[str] = "observer_state"
"""Observer state, labelled ``std_msgs/Float64MultiArray`` (rows x1_hat, x2_hat, x3_hat, bandwidth)."""

CONTROLLER_INTERNALS: Final[str] = "controller_internals"
"""Controller internals, labelled ``std_msgs/Float64MultiArray`` (rows = the controller's internals keys)."""

HW_BRIDGE_INTERNALS: Final[str] = "hw_bridge_internals"
"""What ``hw_bridge_node`` sent to the valves, labelled ``std_msgs/Float64MultiArray`` (rows ``codes``,
``torque`` N m, ``clamped``, ``limit_cut``, ``enabled``, ``measured_torque`` N m from the load pressure),
stamped with the answered measurement."""

CLOCK: Final[str] = "/clock"
"""Simulation clock, ``rosgraph_msgs/Clock``; absolute, published by the simulator in lockstep."""

DIAGNOSTICS: Final[str] = "/diagnostics"
"""Node health, ``diagnostic_msgs/DiagnosticArray``; absolute, the name every ROS monitoring tool reads."""

CONTROL_TOPICS: Final[tuple[str, ...]] = (
    JOINT_STATES,
    JOINT_STATES_FILTERED,
    REFERENCE,
    TORQUE_COMMAND,
    DISTURBANCE_ESTIMATE,
)
"""Topics of the control chain: a lost sample would stall lockstep or corrupt the loop."""

DIAGNOSTIC_TOPICS: Final[tuple[str, ...]] = (
    GROUND_TRUTH,
    OBSERVER_STATE,
    CONTROLLER_INTERNALS,
    HW_BRIDGE_INTERNALS,
)
"""Topics read only by recorders and plots."""

ALL_TOPICS: Final[tuple[str, ...]] = (*CONTROL_TOPICS, *DIAGNOSTIC_TOPICS, CLOCK)


def fully_qualified(topic: str, namespace: str = DEFAULT_NAMESPACE) -> str:
    """Return the absolute name a relative topic gets under ``namespace`` (no remapping applied).

    Used by tools that address topics without a node, e.g. bag readers: ``fully_qualified(JOINT_STATES)``
    is ``"/smm/joint_states"``. Absolute names (``/clock``) are returned unchanged.

    Args:
        topic: A topic name from this module.
        namespace: Namespace with or without leading/trailing slashes; ``""`` means the root.

    Returns:
        The absolute topic name.
    """
    if topic.startswith("/"):
        return topic
    stripped = namespace.strip("/")
    return f"/{stripped}/{topic}" if stripped else f"/{topic}"


TOPIC_TYPES: Final[Mapping[str, type]] = MappingProxyType(
    {
        JOINT_STATES: JointState,
        JOINT_STATES_FILTERED: JointState,
        GROUND_TRUTH: JointState,
        REFERENCE: Float64MultiArray,
        TORQUE_COMMAND: Float64MultiArray,
        DISTURBANCE_ESTIMATE: Float64MultiArray,
        OBSERVER_STATE: Float64MultiArray,
        CONTROLLER_INTERNALS: Float64MultiArray,
        HW_BRIDGE_INTERNALS: Float64MultiArray,
        CLOCK: Clock,
    }
)
"""Message type of each topic, e.g. ``node.create_publisher(TOPIC_TYPES[REFERENCE], REFERENCE, ...)``."""
