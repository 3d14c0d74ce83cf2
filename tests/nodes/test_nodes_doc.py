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


@pytest.mark.parametrize("node_class", [ReferenceNode, TdNode, FlesoNode, ControllerNode])
def test_every_declared_parameter_is_documented_and_nothing_else(ros_context: Any, node_class: Any) -> None:
    node = node_class(context=ros_context)
    try:
        declared = set(node.list_parameters([], 0).names) - ROS_OWN
        assert documented_parameters(node.get_name()) == declared
    finally:
        node.destroy_node()
