"""Two separate processes exchange a JointState over DDS inside the private network namespace."""

from __future__ import annotations

import sys
import textwrap

import pytest

pytestmark = pytest.mark.ros

TALKER = textwrap.dedent(
    """
    import rclpy
    from sensor_msgs.msg import JointState
    rclpy.init()
    node = rclpy.create_node("smoke_talker")
    pub = node.create_publisher(JointState, "smoke_joint_states", 10)
    count = 0
    def tick():
        global count
        msg = JointState()
        msg.header.stamp.sec = count
        msg.name = ["alpha", "beta"]
        msg.position = [0.25 * count, -0.5]
        pub.publish(msg)
        count += 1
    node.create_timer(0.05, tick)
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    """
)

LISTENER = textwrap.dedent(
    """
    import sys
    import rclpy
    from sensor_msgs.msg import JointState
    rclpy.init()
    node = rclpy.create_node("smoke_listener")
    received = []
    node.create_subscription(JointState, "smoke_joint_states", received.append, 10)
    deadline = node.get_clock().now().nanoseconds + 30 * 10**9
    while len(received) < 3 and node.get_clock().now().nanoseconds < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    for msg in received[:3]:
        print(msg.header.stamp.sec, list(msg.name), list(msg.position), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    sys.exit(0 if len(received) >= 3 else 1)
    """
)


def test_two_processes_exchange_joint_state(ros_processes, ros_domain_id: int) -> None:
    talker = ros_processes.start("talker", [sys.executable, "-c", TALKER])
    listener = ros_processes.start("listener", [sys.executable, "-c", LISTENER])
    code = listener.popen.wait(timeout=60)
    assert code == 0, listener.logs() + talker.logs()
    lines = listener.stdout_path.read_text().splitlines()
    assert len(lines) == 3
    stamps = []
    for line in lines:
        sec, rest = line.split(" ", 1)
        stamps.append(int(sec))
        assert "['alpha', 'beta']" in rest
        assert rest.endswith(f"[{0.25 * int(sec)}, -0.5]")
    assert stamps == sorted(stamps)
    assert talker.alive(), talker.logs()


def test_in_process_context_sees_separate_process(ros_processes, ros_context) -> None:
    from ros_harness import MessageCollector, wait_for_topics
    from sensor_msgs.msg import JointState

    talker = ros_processes.start("talker", [sys.executable, "-c", TALKER])
    assert "/smoke_joint_states" in wait_for_topics(ros_context, ["/smoke_joint_states"], timeout_s=30)
    collector = MessageCollector(ros_context, "smoke_joint_states", JointState)
    try:
        messages = collector.wait_for(2, timeout_s=30)
    finally:
        collector.close()
    assert len(messages) >= 2, talker.logs()
    assert list(messages[0].name) == ["alpha", "beta"]


def test_session_runs_in_private_network_namespace(ros_netns) -> None:
    from netns_exec import interface_names

    assert interface_names() == ["lo"]
