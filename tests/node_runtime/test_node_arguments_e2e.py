"""Each node executable refuses a mistyped name, a misspelled node section, a missing or malformed parameter
file and a malformed ``-p`` before any node starts: one line on stderr, exit 2, no traceback."""

from __future__ import annotations

from pathlib import Path

import pytest
from ros_harness import run_side_by_side
from smm_bringup.graph_nodes import NodeSpec
from smm_bringup.supervisor import resolve_executable
from smm_node_runtime.parameter_check import known_names

pytestmark = pytest.mark.ros

TIMEOUT_S = 60.0
"""A refusal comes before rclpy.init; a process still running this long has started its node (a failure)."""

EXECUTABLES = [
    ("smm_sim", "smm_sim_node", "smm_sim_node"),
    ("smm_controller", "td_node", "td_node"),
    ("smm_controller", "fleso_node", "fleso_node"),
    ("smm_controller", "reference_node", "reference_node"),
    ("smm_controller", "controller_node", "controller_node"),
    ("smm_hw_bridge", "hw_bridge_node", "hw_bridge_node"),
    ("smm_bag", "recorder_node", "recorder_node"),
    ("smm_direct_loop", "direct_loop", "controller_node"),
]
"""(package, console script, a node it runs)."""


def _executable(package: str, name: str) -> str:
    return resolve_executable(NodeSpec(package=package, executable=name, name=name, node_class=""))


def _assert_refused(result: tuple[int, str, str], *needles: str) -> None:
    code, _, err = result
    assert code == 2, err
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for needle in needles:
        assert needle in lines[0], err


@pytest.mark.parametrize(("package", "script", "node"), EXECUTABLES, ids=[e[1] for e in EXECUTABLES])
def test_a_node_executable_refuses_an_unknown_name_a_misspelled_section_and_a_missing_file(
    ros_domain_id: int, tmp_path: Path, package: str, script: str, node: str
) -> None:
    executable = _executable(package, script)
    known = sorted(known_names(node))[0]
    typo = tmp_path / "typo.yaml"
    typo.write_text(f"/**/{node}:\n  ros__parameters:\n    {known}x: 1.0\n")
    section = tmp_path / "section.yaml"
    misspelled = node.replace("_node", "_nod")
    section.write_text(f"/{misspelled}:\n  ros__parameters:\n    {known}: 1.0\n")
    missing = tmp_path / "missing.yaml"
    results = run_side_by_side(
        [[executable, "--ros-args", "--params-file", str(path)] for path in (typo, section, missing)],
        TIMEOUT_S,
    )
    _assert_refused(results[0], f"'{known}x'", f"'/**/{node}'", str(typo), f"did you mean '{known}'?")
    _assert_refused(results[1], f"'/{misspelled}'", str(section), "reaches no node")
    _assert_refused(results[2], str(missing))


def test_controller_node_refuses_a_malformed_file_and_malformed_or_unknown_overrides(
    ros_domain_id: int, tmp_path: Path
) -> None:
    executable = _executable("smm_controller", "controller_node")
    malformed = tmp_path / "malformed.yaml"
    malformed.write_text("/**/controller_node:\n  ros__parameters:\n    fpdeso: [1.0,\n")
    results = run_side_by_side(
        [
            [executable, "--ros-args", "--params-file", str(malformed)],
            [executable, "--ros-args", "-p", "fpdeso.fuzzy.kd00:=[1.0, 1.0]"],
            # an unquoted array pasted into a shell: rcl would get "[1.0," and "0.785]"
            [executable, "--ros-args", "-p", "reference.sine.amplitude:=[1.0,", "0.785]"],
            [executable, "--ros-args", "-p", "algorithm"],
        ],
        TIMEOUT_S,
    )
    _assert_refused(results[0], str(malformed), "not valid YAML")
    _assert_refused(results[1], "'fpdeso.fuzzy.kd00'", "did you mean 'fpdeso.fuzzy.kd0'?")
    _assert_refused(results[2], "reference.sine.amplitude", "not YAML", "quote an array")
    _assert_refused(results[3], "-p 'algorithm'", "NAME:=VALUE")
