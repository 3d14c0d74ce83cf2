"""Parameter names and node sections are checked against what the stack's nodes declare (no ROS here)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml
from smm_hw_bridge.canopen_config import CanopenConfig
from smm_node_runtime.parameter_check import (
    Override,
    UnknownParameterError,
    check_node_arguments,
    check_parameters,
    is_ros_parameter,
    known_names,
    known_nodes,
    parse_ros_arguments,
)
from smm_node_runtime.parameter_files import ParameterFileError
from smm_schema.fields import config_fields

CONTROLLER = {"/smm/controller_node": "controller_node"}
"""One running controller_node in /smm (a process started by smm-launch)."""


def _file(tmp_path: Path, sections: dict[str, dict[str, Any]], name: str = "p.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump({key: {"ros__parameters": value} for key, value in sections.items()}))
    return path


def test_the_stack_nodes_and_their_gains_are_known() -> None:
    assert set(known_nodes()) == {
        "smm_sim_node",
        "hw_bridge_node",
        "reference_node",
        "td_node",
        "fleso_node",
        "controller_node",
        "recorder_node",
    }
    assert "fpdeso.fuzzy.kd0" in known_names("controller_node")
    assert "fpdeso.fuzzy.kd00" not in known_names("controller_node")
    assert "td.speed" in known_names("controller_node")  # under some setting
    assert "td.speed" not in known_names("controller_node", {})  # not under its defaults
    assert "td.speed" in known_names("controller_node", {"chain": "internal"})


def test_a_mistyped_gain_is_refused_with_its_section_file_and_closest_name(tmp_path: Path) -> None:
    path = _file(tmp_path, {"/**/controller_node": {"fpdeso": {"fuzzy": {"kd00": [1.0, 1.0]}}}})
    with pytest.raises(UnknownParameterError) as raised:
        check_parameters([path], (), CONTROLLER, "/smm")
    message = str(raised.value)
    assert "'fpdeso.fuzzy.kd00'" in message and "'/**/controller_node'" in message
    assert str(path) in message and "did you mean 'fpdeso.fuzzy.kd0'?" in message
    assert "\n" not in message


@pytest.mark.parametrize("field", [item.name for item in config_fields(CanopenConfig)])
def test_an_old_link_canopen_name_is_refused_with_its_new_name(tmp_path: Path, field: str) -> None:
    assert f"canopen.{field}" in known_names("hw_bridge_node")
    path = _file(tmp_path, {"/**/hw_bridge_node": {"link": {"canopen": {field: 1}}}})
    with pytest.raises(UnknownParameterError) as raised:
        check_parameters([path], (), {"/smm/hw_bridge_node": "hw_bridge_node"}, "/smm")
    message = str(raised.value)
    assert f"unknown parameter 'link.canopen.{field}'" in message
    assert f"did you mean 'canopen.{field}'? (link.canopen.* is now canopen.*)" in message


def test_a_correct_file_passes(tmp_path: Path) -> None:
    path = _file(
        tmp_path,
        {
            "/**/controller_node": {"fpdeso": {"fuzzy": {"kd0": [1.0, 1.0]}}, "use_sim_time": True},
            "/smm/smm_sim_node": {"seed": 3, "qos_overrides": {"/clock": {"publisher": {"depth": 1}}}},
            "/**/reference_node": {"kind": "sine"},
        },
    )
    check_parameters([path], (), CONTROLLER, "/smm")


def test_a_misspelled_node_section_is_refused_with_the_closest_node(tmp_path: Path) -> None:
    path = _file(tmp_path, {"/smm/controler_node": {"fpdeso": {"fuzzy": {"kd0": [1.0, 1.0]}}}})
    with pytest.raises(
        UnknownParameterError, match=r"'/smm/controler_node'.*reaches no node.*'controller_node'"
    ):
        check_parameters([path], (), CONTROLLER, "/smm")


def test_a_section_for_another_namespace_says_where_the_node_runs(tmp_path: Path) -> None:
    path = _file(tmp_path, {"/smm/controller_node": {"fpdeso": {"fuzzy": {"kd0": [1.0, 1.0]}}}})
    with pytest.raises(UnknownParameterError, match=r"controller_node runs as /controller_node here"):
        check_parameters([path], (), {"/controller_node": "controller_node"}, "/")


@pytest.mark.parametrize("key", ["/**", "/smm/*", "/**/*_node"])
def test_a_wildcard_section_takes_the_names_of_every_node_it_reaches(tmp_path: Path, key: str) -> None:
    good = _file(tmp_path, {key: {"seed": 1, "fpdeso": {"robust_gain": [1.0, 1.0]}, "lookahead": 2}})
    check_parameters([good], (), CONTROLLER, "/smm")  # the simulator's, the controller's, the reference's
    bad = _file(tmp_path, {key: {"seed": 1, "sead": 2}}, "bad.yaml")
    with pytest.raises(UnknownParameterError, match=r"unknown parameter 'sead'.*did you mean 'seed'"):
        check_parameters([bad], (), CONTROLLER, "/smm")


def test_a_node_wildcard_reaches_only_its_node(tmp_path: Path) -> None:
    path = _file(tmp_path, {"/**/td_node": {"fpdeso": {"robust_gain": [1.0, 1.0]}}})
    with pytest.raises(UnknownParameterError, match=r"'fpdeso.robust_gain'.*/smm/td_node"):
        check_parameters([path], (), CONTROLLER, "/smm")


def test_a_name_declared_only_under_a_setting_needs_it(tmp_path: Path) -> None:
    path = _file(tmp_path, {"/**/controller_node": {"td": {"speed": [100.0, 100.0]}}})
    with pytest.raises(UnknownParameterError, match=r"'td.speed'.*only with chain: internal"):
        check_parameters([path], (), CONTROLLER, "/smm")
    check_parameters([path], (Override("chain", "internal"),), CONTROLLER, "/smm")
    internal = _file(tmp_path, {"/**/controller_node": {"chain": "internal"}}, "chain.yaml")
    check_parameters([internal, path], (), CONTROLLER, "/smm")
    check_parameters([path], (), {}, "/smm")  # a node not started here: any setting's names


def test_ros_own_parameters_are_allowed() -> None:
    for name in ("use_sim_time", "start_type_description_service", "qos_overrides./clock.publisher.depth"):
        assert is_ros_parameter(name)
    assert not is_ros_parameter("use_sim_timer")


def test_overrides_are_checked_against_the_running_nodes() -> None:
    check_parameters([], (Override("fpdeso.fuzzy.kd0", [1.0, 1.0]),), CONTROLLER, "/smm")
    with pytest.raises(UnknownParameterError, match=r"-p seed:=3.*no such name on /smm/controller_node"):
        check_parameters([], (Override("seed", 3, text="seed:=3"),), CONTROLLER, "/smm")
    with pytest.raises(UnknownParameterError, match=r"reaches no node"):
        check_parameters([], (Override("seed", 3, node="controler_node"),), CONTROLLER, "/smm")


def test_every_ros_args_section_is_read() -> None:
    arguments = parse_ros_arguments(
        [
            "prog",
            "-p",
            "not:=ros",
            "--ros-args",
            "-r",
            "__ns:=/bench",
            "--params-file",
            "a.yaml",
            "--log-level",
            "-p",
            "--",
            "--params-file",
            "ignored.yaml",
            "--ros-args",
            "-p",
            "controller_node:fpdeso.fuzzy.kd0:=[1.0, 2.0]",
            "--remap",
            "__node:=other",
        ]
    )
    assert arguments.files == ("a.yaml",)
    assert arguments.namespace == "/bench" and arguments.node_name == "other"
    assert arguments.overrides == (
        Override(
            "fpdeso.fuzzy.kd0", [1.0, 2.0], "controller_node", "controller_node:fpdeso.fuzzy.kd0:=[1.0, 2.0]"
        ),
    )


@pytest.mark.parametrize(
    ("args", "reason"),
    [
        (["--ros-args", "-p", "seed"], "not a parameter override"),
        (["--ros-args", "-p", "reference.sine.amplitude:=[1.0,"], "not YAML.*quote an array"),
        (["--ros-args", "-p", "seed:="], "not a parameter value"),
        (["--ros-args", "-p", "x:=[1, 2.0]"], "mixes types"),
        (["--ros-args", "-p", "x:={a: 1}"], "not a parameter value"),
        (["--ros-args", "-p"], "has no argument"),
        (["--ros-args", "--params-file"], "has no argument"),
    ],
)
def test_a_malformed_override_is_refused_in_one_line(args: list[str], reason: str) -> None:
    with pytest.raises(ParameterFileError, match=reason) as raised:
        parse_ros_arguments(args)
    assert "\n" not in str(raised.value)


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        ("a: [1,\n", r"not valid YAML: .*\(line 2, column 1\)"),
        ("/**:\n  ros__parameters:\n    seed: [1, 2.0]\n", "mixes types"),
        ("/**:\n  ros__parameters:\n    seed: []\n", "not a parameter value"),
    ],
)
def test_a_malformed_file_is_refused_in_one_line(tmp_path: Path, content: str, reason: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    with pytest.raises(ParameterFileError, match=reason) as raised:
        check_parameters([path], (), CONTROLLER, "/smm")
    assert "\n" not in str(raised.value)


def test_a_missing_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ParameterFileError, match=r"cannot read parameter file .*missing\.yaml"):
        check_parameters([tmp_path / "missing.yaml"], (), CONTROLLER, "/smm")


def test_a_node_process_checks_its_own_name_and_namespace(tmp_path: Path) -> None:
    path = _file(tmp_path, {"/bench/ctl": {"fpdeso": {"fuzzy": {"kd0": [1.0, 1.0]}}}})
    args = ["x", "--ros-args", "-r", "__ns:=/bench", "-r", "__node:=ctl", "--params-file", str(path)]
    assert check_node_arguments(args, ["controller_node"]).files == (str(path),)
    with pytest.raises(UnknownParameterError, match="reaches no node"):
        check_node_arguments([*args[:-4], "--params-file", str(path)], ["controller_node"])
