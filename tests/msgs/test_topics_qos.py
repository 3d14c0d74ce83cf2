"""Topic names, message types and QoS per topic."""

import re

import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

import smm_msgs_py
from smm_msgs_py import qos_for_topic, subscription_qos_for_topic, topics

RELATIVE_NAME = re.compile(r"^[a-z][a-z0-9_]*$")

EXPECTED = {  # type, subscription depth of the loop's nodes; every publisher keeps 1000
    "joint_states": (JointState, 10),
    "joint_states_filtered": (JointState, 10),
    "ground_truth": (JointState, 100),
    "reference": (Float64MultiArray, 10),
    "torque_command": (Float64MultiArray, 10),
    "disturbance_estimate": (Float64MultiArray, 10),
    "observer_state": (Float64MultiArray, 100),
    "controller_internals": (Float64MultiArray, 100),
    "hw_bridge_internals": (Float64MultiArray, 100),
    "/clock": (Clock, 10),
}


def test_every_topic_is_listed_with_its_type() -> None:
    assert sorted(topics.ALL_TOPICS) == sorted(EXPECTED)
    assert {name: topics.TOPIC_TYPES[name] for name in EXPECTED} == {k: v[0] for k, v in EXPECTED.items()}


@pytest.mark.parametrize("name", [t for t in EXPECTED if t != "/clock"])
def test_stack_topics_are_relative_so_the_namespace_applies(name: str) -> None:
    assert RELATIVE_NAME.match(name)
    assert topics.fully_qualified(name) == f"/smm/{name}"
    assert topics.fully_qualified(name, "/bench/") == f"/bench/{name}"
    assert topics.fully_qualified(name, "") == f"/{name}"


def test_clock_is_global() -> None:
    assert topics.CLOCK == "/clock"
    assert topics.fully_qualified(topics.CLOCK) == "/clock"


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_qos_is_reliable_keep_last_with_the_documented_depth_and_durability(name: str) -> None:
    publisher, subscription = qos_for_topic(name), subscription_qos_for_topic(name)
    for profile, depth in ((publisher, 1000), (subscription, EXPECTED[name][1])):
        assert profile.reliability == ReliabilityPolicy.RELIABLE
        assert profile.history == HistoryPolicy.KEEP_LAST
        assert profile.depth == depth
    # Publishers keep their history for a late TRANSIENT_LOCAL reader (a recorder); the loop reads VOLATILE.
    assert publisher.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert subscription.durability == DurabilityPolicy.VOLATILE


def test_qos_profiles_are_not_shared() -> None:
    first = qos_for_topic(topics.TORQUE_COMMAND)
    first.depth = 1
    assert qos_for_topic(topics.TORQUE_COMMAND).depth == 1000


def test_unknown_topic_has_no_qos() -> None:
    with pytest.raises(KeyError, match="joint_state"):
        qos_for_topic("joint_state")
    with pytest.raises(KeyError, match="joint_state"):
        subscription_qos_for_topic("joint_state")


def test_public_api_is_importable() -> None:
    for name in smm_msgs_py.__all__:
        assert hasattr(smm_msgs_py, name), name
