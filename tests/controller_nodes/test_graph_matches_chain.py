"""The controller nodes, run in-process against smm_sim.plant, give the torques of ControlChain.

Both layouts: the split chain (td_node, fleso_node, reference_node, controller_node with ``chain:
external``) and the fused one (reference_node, controller_node with ``chain: internal``), with and without
the plant reporting the applied torque.

The test plays the simulator: it publishes each measurement of the plant on joint_states, waits for the
torque command stamped with it, checks that command against ``ControlChain.step`` fed the same inputs, and
steps the plant with it. Nodes and chain use the same algorithm code, so the torques must agree exactly.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from controller_nodes.node_rig import measurement
from smm_controller.chain import make_chain
from smm_controller.controller_node import ControllerNode
from smm_controller.fleso_node import FlesoNode
from smm_controller.reference import SineReference
from smm_controller.reference_node import ReferenceNode
from smm_controller.td_node import TdNode
from smm_msgs_py.conversions import msg_to_torque
from smm_sim.plant import PlantConfig, SimulatedPlant

from smm_dynamics import SMMParameters
from smm_msgs_py import topics

pytestmark = pytest.mark.ros

DT = 1e-3


LAYOUTS = {
    # layout: (controller_node's chain parameter, whether the plant reports the applied torque)
    "split": ("external", True),
    "fused": ("internal", True),
    "fused-without-effort": ("internal", False),
}


@pytest.mark.parametrize(
    ("algorithm", "steps", "layout"),
    [
        ("fpdeso", 300, "split"),
        ("pid", 150, "split"),
        ("fpdeso", 300, "fused"),
        ("npd", 150, "fused"),
        ("fpdeso", 200, "fused-without-effort"),
    ],
)
def test_node_graph_reproduces_the_offline_chain(
    make_rig: Any, ros_context: Any, algorithm: str, steps: int, layout: str
) -> None:
    chain, with_effort = LAYOUTS[layout]
    nodes: list[Any] = [
        ReferenceNode(context=ros_context, parameter_overrides={"kind": "sine"}),
        ControllerNode(context=ros_context, parameter_overrides={"algorithm": algorithm, "chain": chain}),
    ]
    if chain == "external":
        nodes.append(TdNode(context=ros_context))
        if algorithm == "fpdeso":
            nodes.append(FlesoNode(context=ros_context))
    rig = make_rig(*nodes)
    torques = rig.record(topics.TORQUE_COMMAND)
    chain = make_chain(algorithm, SMMParameters())
    reference = SineReference()
    plant = SimulatedPlant(PlantConfig(noise_std=(0.001, 0.001), seed=7, inertia_scale=1.1))
    node_torques = []
    chain_torques = []
    for k in range(steps):
        sample = plant.measure()
        effort = sample.applied_torque if with_effort else None
        rig.publish(topics.JOINT_STATES, measurement(sample.stamp_ns, sample.position, effort))
        rig.wait_for(topics.TORQUE_COMMAND, k + 1)
        command = msg_to_torque(torques[k])
        assert command.stamp_ns == sample.stamp_ns
        expected = chain.step(
            sample.position, sample.applied_torque, reference.evaluate(sample.stamp_ns / 1e9), DT
        )
        node_torques.append(command.values)
        chain_torques.append(expected)
        plant.step(command.values, DT)
    np.testing.assert_array_equal(np.array(node_torques), np.array(chain_torques))  # bit for bit
    assert np.ptp(np.array(node_torques), axis=0).min() > 0.0  # the loop really moved
    for node in nodes:
        assert node.counters.dropped_invalid == 0
        assert node.counters.dropped_unmatched == 0
