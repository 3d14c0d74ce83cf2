"""docs/NODES.md lists exactly the parameters each node declares (so the tables cannot go stale)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
from smm_controller.controller_node import ControllerNode
from smm_controller.fleso_node import FlesoNode
from smm_controller.reference_node import ReferenceNode
from smm_controller.td_node import TdNode

pytestmark = pytest.mark.ros

DOC = Path(__file__).resolve().parents[2] / "docs" / "NODES.md"
ROS_OWN = {"use_sim_time", "start_type_description_service"}  # declared by rclpy itself


def documented_parameters(node_name: str) -> set[str]:
    text = DOC.read_text()
    match = re.search(rf"^## {node_name}\n(.*?)(?=^## |\Z)", text, flags=re.MULTILINE | re.DOTALL)
    assert match is not None, f"no section for {node_name} in {DOC}"
    return set(re.findall(r"^\| `([^`]+)` \|", match.group(1), flags=re.MULTILINE))


INTERNAL_ONLY = re.compile(r"^(td|fleso|reference)\.")
"""Parameters controller_node declares only with ``chain: internal`` (td, fleso) or
``reference_source: internal`` (reference)."""


@pytest.mark.parametrize("node_class", [ReferenceNode, TdNode, FlesoNode, ControllerNode])
def test_every_declared_parameter_is_documented_and_nothing_else(ros_context: Any, node_class: Any) -> None:
    node = node_class(context=ros_context)
    try:
        declared = set(node.list_parameters([], 0).names) - ROS_OWN
        documented = documented_parameters(node.get_name())
        if node_class is ControllerNode:
            documented = {name for name in documented if not INTERNAL_ONLY.match(name)}
        assert documented == declared
    finally:
        node.destroy_node()


def test_controller_node_with_the_internal_chain_and_reference_declares_the_documented_parameters(
    ros_context: Any,
) -> None:
    node = ControllerNode(
        context=ros_context, parameter_overrides={"chain": "internal", "reference_source": "internal"}
    )
    try:
        declared = set(node.list_parameters([], 0).names) - ROS_OWN
        assert documented_parameters(node.get_name()) == declared
        prefixes = {name.split(".")[0] for name in declared if INTERNAL_ONLY.match(name)}
        assert prefixes == {"td", "fleso", "reference"}
    finally:
        node.destroy_node()


def test_controller_reference_parameters_mirror_reference_node(ros_context: Any) -> None:
    """reference.<name> on controller_node is reference_node's <name>, with the same description."""
    controller = ControllerNode(context=ros_context, parameter_overrides={"reference_source": "internal"})
    reference = ReferenceNode(context=ros_context)
    try:
        generator_names = [
            name
            for name in reference.list_parameters([], 0).names
            if name not in ROS_OWN and name not in {"control_period", "lookahead"}
        ]
        assert generator_names
        for name in generator_names:
            ours = controller.describe_parameter(f"reference.{name}")
            theirs = reference.describe_parameter(name)
            assert ours.description == theirs.description
            assert controller.get_parameter(f"reference.{name}").value == reference.get_parameter(name).value
    finally:
        controller.destroy_node()
        reference.destroy_node()
