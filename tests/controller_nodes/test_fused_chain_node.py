"""controller_node with ``chain: internal``: TD -> FLESO -> law in one node, on joint_states and reference.

The torques against ``ControlChain`` over a closed loop are checked in test_graph_matches_chain.py; here:
inputs, bad input, the TD/FLESO parameters (rejected with the reason, applied live with the state kept),
the read-only placement, and the internals.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from controller_nodes.node_rig import measurement
from controller_nodes.test_fleso_controller_nodes import bad_arrays, reference_msg
from controller_nodes.test_td_reference_nodes import bad_measurements
from rclpy.parameter import Parameter
from smm_controller.chain import ControlChain
from smm_controller.controller_node import ControllerNode
from smm_controller.fleso import FLESO, FLESOConfig
from smm_controller.fpdeso import FPDESOController
from smm_controller.reference import SineReference
from smm_controller.td import TrackingDifferentiator, TrackingDifferentiatorConfig
from smm_msgs_py.conversions import msg_to_labelled, msg_to_torque

from smm_dynamics import SMMParameters
from smm_msgs_py import topics

pytestmark = pytest.mark.ros

MS = 1_000_000
DT = 1e-3
POSITIONS = [(0.01 * k, -0.02 * k) for k in range(6)]
EFFORTS = [(0.3 * k, -0.1 * k) for k in range(6)]


def fused_node(context: Any, **overrides: Any) -> ControllerNode:
    return ControllerNode(context=context, parameter_overrides={"chain": "internal", **overrides})


def paper_chain(
    td: TrackingDifferentiatorConfig | None = None, fleso: FLESOConfig | None = None
) -> ControlChain:
    model = SMMParameters()
    return ControlChain(TrackingDifferentiator(td), FLESO(fleso, model), FPDESOController(None, model))


def feed(rig: Any, k: int) -> None:
    rig.publish(topics.REFERENCE, reference_msg(k * MS))
    rig.publish(topics.JOINT_STATES, measurement(k * MS, POSITIONS[k], EFFORTS[k]))


def expected_torque(chain: ControlChain, k: int) -> np.ndarray:
    reference = SineReference().evaluate(k * MS / 1e9)
    return chain.step(np.array(POSITIONS[k]), np.array(EFFORTS[k]), reference, DT)


def test_fused_node_waits_for_measurement_and_reference_and_runs_the_whole_chain(
    make_rig: Any, ros_context: Any
) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    internals = rig.record(topics.CONTROLLER_INTERNALS)
    rig.publish(topics.JOINT_STATES, measurement(0, POSITIONS[0], EFFORTS[0]))
    rig.settle(0.1)
    assert torques == []  # the reference of that stamp is missing
    rig.publish(topics.REFERENCE, reference_msg(0))
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    chain = paper_chain()
    np.testing.assert_array_equal(msg_to_torque(torques[0]).values, expected_torque(chain, 0))
    rig.wait_for(topics.CONTROLLER_INTERNALS, 1)
    rows = msg_to_labelled(internals[0]).row_labels
    assert {"td.x1", "fleso.x3_hat", "controller.tau", "disturbance_estimate", "dropped_invalid"} <= set(rows)


def test_fused_node_drops_bad_input_on_every_subscription_and_sends_no_torque(
    make_rig: Any, ros_context: Any
) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    bad = [(topics.JOINT_STATES, msg) for msg in bad_measurements(MS).values()]
    bad += [(topics.REFERENCE, msg) for msg in bad_arrays(reference_msg, MS).values()]
    for topic, msg in bad:
        rig.publish(topic, msg)
    rig.settle(0.1)
    assert torques == []
    feed(rig, 2)
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    rig.settle()
    assert [msg_to_torque(m).stamp_ns for m in torques] == [2 * MS]
    assert node.counters.dropped_invalid == len(bad)


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("td.speed", [-1.0, 1.0], "speed"),
        ("td.filter_factor", [1e-3], "td.filter_factor must have 2 values (alpha, beta), got 1"),
        ("td.filter_factor", [5e-4, 1e-3], "td.filter_factor (0.0005, 0.001) must be >= control_period"),
        ("fleso.w0", [0.0, 28.0], "w0"),
        ("fleso.grid_points", 2, "grid_points"),
    ],
)
def test_invalid_td_and_fleso_gains_are_rejected_with_the_reason(
    make_rig: Any, ros_context: Any, name: str, value: Any, reason: str
) -> None:
    node = fused_node(ros_context)
    make_rig(node)
    assert node.chain is not None
    td_before, fleso_before = node.chain.td.config, node.chain.fleso.config  # type: ignore[union-attr]
    (result,) = node.set_parameters([Parameter(name, value=value)])
    assert not result.successful
    assert reason in result.reason
    assert node.chain.td.config == td_before
    assert node.chain.fleso.config == fleso_before  # type: ignore[union-attr]


def test_td_and_fleso_gain_changes_act_on_the_next_step_and_keep_the_state(
    make_rig: Any, ros_context: Any
) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    kept = paper_chain()
    for k in range(3):
        feed(rig, k)
        rig.wait_for(topics.TORQUE_COMMAND, k + 1)
        expected_torque(kept, k)
    new_td = TrackingDifferentiatorConfig(speed=(2e4, 3e4), filter_factor=(2e-3, 2e-3))
    new_fleso = FLESOConfig(w0=(30.0, 40.0))
    results = node.set_parameters(
        [
            Parameter("td.speed", value=list(new_td.speed)),
            Parameter("td.filter_factor", value=list(new_td.filter_factor)),
            Parameter("fleso.w0", value=list(new_fleso.w0)),
        ]
    )
    assert all(result.successful for result in results), results
    kept.td.reconfigure(new_td)
    assert kept.fleso is not None
    kept.fleso.reconfigure(new_fleso)
    restarted = paper_chain(new_td, new_fleso)
    for k in range(3, 6):
        feed(rig, k)
        rig.wait_for(topics.TORQUE_COMMAND, k + 1)
        expected = expected_torque(kept, k)
        np.testing.assert_array_equal(msg_to_torque(torques[k]).values, expected)
    # A chain rebuilt with the new gains (state lost) would answer differently.
    assert not np.allclose(expected, expected_torque(restarted, 5))


def test_chain_placement_is_read_only_and_checked_at_start(make_rig: Any, ros_context: Any) -> None:
    with pytest.raises(ValueError, match="chain must be one of"):
        fused_node(ros_context, chain="sideways")
    node = fused_node(ros_context)
    make_rig(node)
    (result,) = node.set_parameters([Parameter("chain", value="external")])
    assert not result.successful
    assert node.internal_chain


def test_external_chain_declares_no_td_or_fleso_gains(ros_context: Any) -> None:
    node = ControllerNode(context=ros_context)
    try:
        assert node.chain is None
        assert not node.has_parameter("td.speed") and not node.has_parameter("fleso.w0")
    finally:
        node.destroy_node()


def test_a_non_finite_chain_output_sends_nothing(make_rig: Any, ros_context: Any) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    huge = measurement(0, (1e308, 1e308), (0.0, 0.0))  # finite input, overflowing torque
    rig.publish(topics.REFERENCE, reference_msg(0))
    rig.publish(topics.JOINT_STATES, huge)
    rig.settle(0.2)
    assert torques == []
    assert node.counters.invalid_outputs == 1


def test_fused_node_re_answers_a_duplicate_and_drops_a_stale_measurement(
    make_rig: Any, ros_context: Any
) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    chain = paper_chain()
    for k in (1, 2):
        feed(rig, k)
        rig.wait_for(topics.TORQUE_COMMAND, k)
        expected_torque(chain, k)
    rig.publish(topics.JOINT_STATES, measurement(2 * MS, POSITIONS[2], EFFORTS[2]))  # re-transmission
    rig.wait_for(topics.TORQUE_COMMAND, 3)
    assert list(torques[2].data) == list(torques[1].data)  # the same answer, the chain not stepped again
    rig.publish(topics.JOINT_STATES, measurement(MS, POSITIONS[1], EFFORTS[1]))  # stale: dropped
    feed(rig, 3)
    rig.wait_for(topics.TORQUE_COMMAND, 4)
    rig.settle()
    assert len(torques) == 4
    np.testing.assert_array_equal(msg_to_torque(torques[3]).values, expected_torque(chain, 3))
    assert node.counters.duplicates_answered == 1
    assert node.counters.dropped_stale == 1
