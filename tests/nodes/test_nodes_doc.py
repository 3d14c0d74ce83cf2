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


INTERNAL_ONLY = re.compile(r"^(td|fleso)\.")
"""Parameters controller_node declares only with ``chain: internal``."""


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


def test_controller_node_with_the_internal_chain_declares_the_documented_td_and_fleso_parameters(
    ros_context: Any,
) -> None:
    node = ControllerNode(context=ros_context, parameter_overrides={"chain": "internal"})
    try:
        declared = set(node.list_parameters([], 0).names) - ROS_OWN
        assert documented_parameters(node.get_name()) == declared
        assert {name for name in declared if INTERNAL_ONLY.match(name)}  # td.* and fleso.* are there
    finally:
        node.destroy_node()
