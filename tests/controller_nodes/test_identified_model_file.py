"""A model.yaml of smm-bag identify, given as it is, sets the model of controller_node and fleso_node."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from smm_analysis.identify_command import model_sections
from smm_analysis.parameters_file import write_parameters_file
from smm_bringup.parameter_files import load_parameter_file
from smm_controller.controller_node import ControllerNode
from smm_controller.fleso_node import FlesoNode

from smm_dynamics import SMMParameters

pytestmark = pytest.mark.ros

IDENTIFIED = SMMParameters(
    I11=0.071,
    I22=0.083,
    I44=0.069,
    I55=0.077,
    mass_lever=0.043,
    viscous_friction=(0.12, 0.2),
    coulomb_friction=(0.05, 0.08),
    torque_offset=(-0.02, 0.03),
)


@pytest.mark.parametrize("node_class", [ControllerNode, FlesoNode])
def test_nodes_take_the_identified_model(ros_context: Any, node_class: Any, tmp_path: Path) -> None:
    path = write_parameters_file(tmp_path / "model.yaml", model_sections(IDENTIFIED))
    overrides = load_parameter_file(path, f"/smm/{node_class.__name__.removesuffix('Node').lower()}_node")
    node = node_class(context=ros_context, parameter_overrides=overrides)
    try:
        assert node.model_parameters.config == IDENTIFIED
    finally:
        node.destroy_node()
