"""The shipped parameter files (smm_controller/config/*.yaml) hold the paper's gain sets, completely.

Each file is read twice: as plain YAML, to check it names every field of the config (so the defaults
cannot silently stand in for a missing line) and gives the paper's values; and by rcl itself, through
``--params-file`` on a node in the /smm namespace, to check that ROS accepts every value with its declared
type (e.g. no integer array for a double-array parameter) and that the node ends up with the paper's config.
"""

from __future__ import annotations

import json
from typing import Any

import pytest
import yaml
from smm_bringup.parameter_files import load_parameter_file, package_file
from smm_controller.baselines import FPDConfig, NPDConfig, PIDConfig
from smm_controller.controller_node import ControllerNode
from smm_controller.fleso import FLESOConfig
from smm_controller.fleso_node import FlesoNode
from smm_controller.fpdeso import FPDESOConfig
from smm_controller.fuzzy_pd import PAPER_FPD_FUZZY, PAPER_FPDESO_FUZZY
from smm_schema.fields import config_fields, config_from_parameters, config_to_parameters

PAPER = {
    "fpdeso": FPDESOConfig(fuzzy=PAPER_FPDESO_FUZZY),
    "fpd": FPDConfig(fuzzy=PAPER_FPD_FUZZY),
    "pid": PIDConfig(),
    "npd": NPDConfig(),
}
PAPER_FLESO = FLESOConfig()


def flatten(prefix: str, values: dict[str, Any]) -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for key, value in values.items():
        name = f"{prefix}.{key}" if prefix else key
        flat.update(flatten(name, value) if isinstance(value, dict) else {name: value})
    return flat


def section(algorithm: str, key: str) -> dict[str, Any]:
    content = yaml.safe_load(package_file("smm_controller", f"config/{algorithm}.yaml").read_text())
    return flatten("", content[key]["ros__parameters"])


@pytest.mark.parametrize("algorithm", sorted(PAPER))
def test_file_sets_every_gain_of_its_law_to_the_paper_value(algorithm: str) -> None:
    values = section(algorithm, "/**/controller_node")
    assert values["algorithm"] == algorithm
    config_cls = type(PAPER[algorithm])
    expected_names = {f"{algorithm}.{f.name}" for f in config_fields(config_cls)}
    gains = {name: value for name, value in values.items() if name != "algorithm"}
    assert set(gains) == expected_names
    paper_values = config_to_parameters(PAPER[algorithm], prefix=algorithm)
    # JSON tells 4050 from 4050.0: ROS would refuse an integer for a double parameter.
    assert json.dumps(gains, sort_keys=True) == json.dumps(
        {n: paper_values[n] for n in expected_names}, sort_keys=True
    )
    assert config_from_parameters(config_cls, config_cls(), gains, prefix=algorithm) == PAPER[algorithm]


def test_fpdeso_file_sets_every_fleso_gain_to_the_paper_value() -> None:
    values = section("fpdeso", "/**")
    expected = config_to_parameters(PAPER_FLESO, prefix="fleso")
    assert json.dumps(values, sort_keys=True) == json.dumps(expected, sort_keys=True)
    assert config_from_parameters(FLESOConfig, FLESOConfig(), values, prefix="fleso") == PAPER_FLESO


@pytest.mark.parametrize("node", ["fleso_node", "controller_node"])
def test_fpdeso_file_gives_the_fleso_gains_to_whichever_node_runs_the_fleso(node: str) -> None:
    path = package_file("smm_controller", "config/fpdeso.yaml")
    values = load_parameter_file(path, f"/smm/{node}")
    fleso = {name: value for name, value in values.items() if name.startswith("fleso.")}
    assert fleso == config_to_parameters(PAPER_FLESO, prefix="fleso")


@pytest.mark.ros
@pytest.mark.parametrize("algorithm", sorted(PAPER))
def test_rcl_loads_each_file_into_the_node_configs(ros_context: Any, algorithm: str) -> None:
    path = str(package_file("smm_controller", f"config/{algorithm}.yaml"))
    node = ControllerNode(
        context=ros_context, namespace="smm", cli_args=["--ros-args", "--params-file", path]
    )
    try:
        assert node.algorithm == algorithm  # the file was applied: the default algorithm is fpdeso
        assert node.law_parameters[algorithm].config == PAPER[algorithm]
    finally:
        node.destroy_node()
    fused = ControllerNode(
        context=ros_context,
        namespace="smm",
        cli_args=["--ros-args", "--params-file", path, "-p", "chain:=internal"],
    )
    try:
        assert fused.algorithm == algorithm
        assert fused.law_parameters[algorithm].config == PAPER[algorithm]
        assert fused.fleso_parameters.config == PAPER_FLESO
    finally:
        fused.destroy_node()
    if algorithm == "fpdeso":
        fleso = FlesoNode(
            context=ros_context, namespace="smm", cli_args=["--ros-args", "--params-file", path]
        )
        try:
            assert fleso.fleso_parameters.config == PAPER_FLESO
            assert fleso.fleso.config == PAPER_FLESO
        finally:
            fleso.destroy_node()
