"""controller_node with ``reference_source: internal``: it samples the reference itself.

Checked: the torques equal ``ControlChain`` / the law fed with the generator's reference at
t = (stamp - first stamp) / 1e9 s, bit for bit; ``reference`` is not read but published (after the command,
for recorders) with the values used; the ``reference.*`` parameters are validated and applied live; the
source is read-only and checked at start.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from controller_nodes.node_rig import filtered, measurement
from controller_nodes.test_fleso_controller_nodes import estimate_msg
from controller_nodes.test_fused_chain_node import EFFORTS, POSITIONS, paper_chain
from rclpy.parameter import Parameter
from smm_controller.controller_node import ControllerNode
from smm_controller.fpdeso import FPDESOController
from smm_controller.reference import RampHoldReference, SineReference
from smm_msgs_py.conversions import msg_to_reference, msg_to_torque

from smm_dynamics import SMMParameters
from smm_msgs_py import topics

pytestmark = pytest.mark.ros

MS = 1_000_000
DT = 1e-3
FIRST = 7  # the first stamp is 7 ms: t counts from it, not from 0


def sampling_node(context: Any, chain: str = "internal", **overrides: Any) -> ControllerNode:
    return ControllerNode(
        context=context,
        parameter_overrides={"chain": chain, "reference_source": "internal", **overrides},
    )


def stamp(k: int) -> int:
    return (FIRST + k) * MS


@pytest.mark.parametrize(
    "generator",
    [SineReference(), SineReference(amplitude=(0.3, -0.2), angular_frequency=5.0, phase=(0.1, 1.0))],
)
def test_fused_node_answers_each_measurement_with_the_sampled_reference(
    make_rig: Any, ros_context: Any, generator: SineReference
) -> None:
    node = sampling_node(
        ros_context,
        **{
            "reference.sine.amplitude": list(generator.amplitude),
            "reference.sine.angular_frequency": generator.angular_frequency,
            "reference.sine.phase": list(generator.phase),
        },
    )
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    references = rig.record(topics.REFERENCE)
    chain = paper_chain()
    for k in range(4):
        rig.publish(topics.JOINT_STATES, measurement(stamp(k), POSITIONS[k], EFFORTS[k]))
        rig.wait_for(topics.TORQUE_COMMAND, k + 1)
        expected = chain.step(
            np.array(POSITIONS[k]), np.array(EFFORTS[k]), generator.evaluate(k * MS / 1e9), DT
        )
        np.testing.assert_array_equal(msg_to_torque(torques[k]).values, expected)
    rig.wait_for(topics.REFERENCE, 4)
    for k, msg in enumerate(references):
        published = msg_to_reference(msg)
        assert published.stamp_ns == stamp(k)
        np.testing.assert_array_equal(published.values, generator.evaluate(k * MS / 1e9))


def test_the_reference_topic_is_not_read(make_rig: Any, ros_context: Any) -> None:
    node = sampling_node(ros_context)
    make_rig(node)
    assert topics.REFERENCE not in {
        subscription.topic_name.rsplit("/", 1)[-1] for subscription in node.subscriptions
    }
    assert node.sync.inputs == {topics.JOINT_STATES}


def test_external_chain_steps_the_law_with_the_sampled_reference(make_rig: Any, ros_context: Any) -> None:
    node = sampling_node(ros_context, chain="external")
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    assert set(node.sync.inputs) == {topics.JOINT_STATES_FILTERED, topics.DISTURBANCE_ESTIMATE}
    law = FPDESOController(None, SMMParameters())
    position, velocity, xi = (0.1, -0.2), (0.5, 0.3), (0.2, -0.1)
    for k in range(3):
        rig.publish(topics.JOINT_STATES_FILTERED, filtered(stamp(k), position, velocity))
        rig.publish(topics.DISTURBANCE_ESTIMATE, estimate_msg(stamp(k), xi, velocity))
        rig.wait_for(topics.TORQUE_COMMAND, k + 1)
        reference = SineReference().evaluate(k * MS / 1e9)
        expected = law.step(reference, np.array(position), np.array(velocity), np.array(xi), DT)
        np.testing.assert_array_equal(msg_to_torque(torques[k]).values, expected)


def test_reference_parameters_are_checked_and_act_on_the_next_step(make_rig: Any, ros_context: Any) -> None:
    node = sampling_node(ros_context)
    rig = make_rig(node)
    references = rig.record(topics.REFERENCE)
    (bad_kind,) = node.set_parameters([Parameter("reference.kind", value="zigzag")])
    assert not bad_kind.successful and "kind must be one of" in bad_kind.reason
    (bad_time,) = node.set_parameters([Parameter("reference.ramp_hold.ramp_time", value=0.0)])
    assert not bad_time.successful and "ramp_time" in bad_time.reason
    rig.publish(topics.JOINT_STATES, measurement(stamp(0), POSITIONS[0], EFFORTS[0]))
    rig.wait_for(topics.REFERENCE, 1)
    results = node.set_parameters(
        [
            Parameter("reference.kind", value="ramp_hold"),
            Parameter("reference.ramp_hold.target", value=[0.4, -0.3]),
            Parameter("reference.ramp_hold.ramp_time", value=0.01),
        ]
    )
    assert all(result.successful for result in results), results
    rig.publish(topics.JOINT_STATES, measurement(stamp(1), POSITIONS[1], EFFORTS[1]))
    rig.wait_for(topics.REFERENCE, 2)
    ramp = RampHoldReference(target=(0.4, -0.3), ramp_time=0.01)
    np.testing.assert_array_equal(msg_to_reference(references[0]).values, SineReference().evaluate(0.0))
    np.testing.assert_array_equal(msg_to_reference(references[1]).values, ramp.evaluate(1e-3))


def test_reference_source_is_read_only_and_checked_at_start(make_rig: Any, ros_context: Any) -> None:
    with pytest.raises(ValueError, match="reference_source must be one of"):
        ControllerNode(context=ros_context, parameter_overrides={"reference_source": "psychic"})
    node = sampling_node(ros_context)
    make_rig(node)
    (result,) = node.set_parameters([Parameter("reference_source", value="topic")])
    assert not result.successful
    assert node.internal_reference


def test_topic_source_declares_no_reference_parameters(ros_context: Any) -> None:
    node = ControllerNode(context=ros_context, parameter_overrides={"chain": "internal"})
    try:
        assert node.reference is None
        assert not node.has_parameter("reference.kind")
    finally:
        node.destroy_node()


def test_the_fused_chain_admits_through_the_core_as_the_direct_loop_does(
    make_rig: Any, ros_context: Any
) -> None:
    """One admission path: each joint_states goes through ControllerCore.measurement, whose answer is sent."""
    node = sampling_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    seen: list[int] = []
    measure = node.core.measurement

    def recorded(topic: str, stamp_ns: int, *rest: Any) -> Any:
        seen.append(stamp_ns)
        return measure(topic, stamp_ns, *rest)

    node.core.measurement = recorded  # type: ignore[method-assign]
    for k in range(3):
        rig.publish(topics.JOINT_STATES, measurement(stamp(k), POSITIONS[k], EFFORTS[k]))
        rig.wait_for(topics.TORQUE_COMMAND, k + 1)
    rig.publish(topics.JOINT_STATES, measurement(stamp(1), POSITIONS[1], EFFORTS[1]))  # an old stamp: refused
    rig.publish(topics.JOINT_STATES, measurement(stamp(3), POSITIONS[3], EFFORTS[3]))
    rig.wait_for(topics.TORQUE_COMMAND, 4)
    assert seen == [stamp(0), stamp(1), stamp(2), stamp(1), stamp(3)]
    assert [msg_to_torque(msg).stamp_ns for msg in torques] == [stamp(0), stamp(1), stamp(2), stamp(3)]
    assert node.counters.dropped_stale == 1
