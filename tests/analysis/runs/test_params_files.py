"""``smm-bag rerun --params-file`` reads a parameter file as smm-launch (rcl) does for the chain's nodes,
and refuses its unknown names and node sections as smm-launch does."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from smm_analysis.errors import ParamsFileError, UnknownParameterError
from smm_analysis.runs.rerun import CHAIN_NODES, NAMESPACE, chain_settings, read_params_files
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import CONTROLLER_NODE, FLESO_NODE, TD_NODE
from smm_bringup.graph_nodes import NAMESPACE as GRAPH_NAMESPACE
from smm_bringup.graph_options import GraphOptions

from smm_bringup import graph_nodes

SECTIONS: dict[str, dict[str, Any]] = {
    "/**": {"td": {"speed": [5000.0, 6000.0]}, "fpdeso": {"fuzzy": {"kp0": [100.0, 110.0]}}},
    "/smm/controller_node": {"fpdeso": {"fuzzy": {"kp0": [200.0, 210.0]}}, "fleso": {"w0": [30.0, 31.0]}},
    "/**/controller_node": {"fleso": {"w0": [40.0, 41.0], "k_w": [12.0, 21.0]}},
}
"""A wildcard, an exact key of the graph's controller_node, a node wildcard."""


def _write(path: Path, keys: list[str], sections: dict[str, dict[str, Any]]) -> Path:
    path.write_text(
        yaml.safe_dump({key: {"ros__parameters": sections[key]} for key in keys}, sort_keys=False)
    )
    return path


def _graph_controller_parameters(path: Path) -> dict[str, Any]:
    """What smm-launch gives controller_node for this file (files, then its explicit overrides)."""
    specs = build_graph(GraphOptions(params_files=(str(path),)))
    controller = next(spec for spec in specs if spec.name == CONTROLLER_NODE)
    return graph_nodes.parameter_overrides(controller)


def test_the_chain_nodes_have_the_graphs_names() -> None:
    assert NAMESPACE == GRAPH_NAMESPACE
    assert set(CHAIN_NODES) == {CONTROLLER_NODE, TD_NODE, FLESO_NODE}


@settings(max_examples=24, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.permutations(list(SECTIONS)))
def test_rerun_and_the_graph_give_controller_node_the_same_values(tmp_path: Path, keys: list[str]) -> None:
    path = _write(tmp_path / "gains.yaml", keys, SECTIONS)
    read = read_params_files([path])
    launched = _graph_controller_parameters(path)
    assert {name: launched[name] for name in read} == read
    assert chain_settings(read) == chain_settings(launched)
    # exact key over every wildcard, whatever the order
    assert read["fpdeso.fuzzy.kp0"] == [200.0, 210.0]
    assert read["fleso.w0"] == [30.0, 31.0]
    assert read["fleso.k_w"] == [12.0, 21.0]
    assert read["td.speed"] == [5000.0, 6000.0]


@pytest.mark.parametrize("first", [TD_NODE, CONTROLLER_NODE])
def test_controller_node_wins_over_the_split_graphs_nodes(tmp_path: Path, first: str) -> None:
    sections = {
        f"/smm/{TD_NODE}": {"td": {"speed": [1000.0, 1000.0]}, "measurement": {"max_speed": [1.0, 1.0]}},
        f"/smm/{FLESO_NODE}": {"fleso": {"w0": [25.0, 26.0]}, "model": {"I11": 0.05}},
        f"/smm/{CONTROLLER_NODE}": {"td": {"speed": [2000.0, 2000.0]}},
    }
    keys = sorted(sections, key=lambda key: not key.endswith(first))
    read = read_params_files([_write(tmp_path / "split.yaml", keys, sections)])
    assert read == {"td.speed": [2000.0, 2000.0], "fleso.w0": [25.0, 26.0], "model.I11": 0.05}


def test_a_split_graph_file_still_sets_the_chain(tmp_path: Path) -> None:
    sections = {
        "/**/td_node": {"td": {"speed": [1000.0, 1000.0]}},
        "/**/fleso_node": {"fleso": {"w0": [25.0, 26.0]}},
    }
    read = read_params_files([_write(tmp_path / "split.yaml", list(sections), sections)])
    assert read == {"td.speed": [1000.0, 1000.0], "fleso.w0": [25.0, 26.0]}


def test_later_files_win_and_the_namespace_is_the_runs(tmp_path: Path) -> None:
    first = _write(tmp_path / "a.yaml", ["/**"], {"/**": {"td": {"speed": [1.0, 1.0]}}})
    second = _write(
        tmp_path / "b.yaml",
        ["/bench/controller_node"],
        {"/bench/controller_node": {"td": {"speed": [2.0, 2.0]}}},
    )
    assert read_params_files([first, second], "bench") == {"td.speed": [2.0, 2.0]}
    with pytest.raises(UnknownParameterError, match="controller_node runs as /smm/controller_node here"):
        read_params_files([second])


def test_a_file_for_other_nodes_only_is_refused_with_the_names_it_needs(tmp_path: Path) -> None:
    sections = {"/smm/smm_sim_node": {"seed": 1}, "/**/reference_node": {"kind": "sine"}}
    path = _write(tmp_path / "other.yaml", list(sections), sections)
    with pytest.raises(ParamsFileError, match=r"no section for /smm/controller_node.*/smm/smm_sim_node"):
        read_params_files([path])


@pytest.mark.parametrize("content", ["- 1\n", "/**:\n  params: {}\n", "a: [1,\n"])
def test_a_file_that_is_not_a_parameter_file_is_refused(tmp_path: Path, content: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    with pytest.raises(ParamsFileError, match=str(path)):
        read_params_files([path])


SAMPLE = Path(__file__).resolve().parents[3] / "bags" / "sample_case2_fpdeso"


@pytest.mark.parametrize(
    ("content", "needles"),
    [
        (
            "/**/controller_node:\n  ros__parameters:\n    fpdeso:\n      fuzzy:\n        kd00: [1.0, 1.0]\n",
            ["'fpdeso.fuzzy.kd00'", "'/**/controller_node'", "did you mean 'fpdeso.fuzzy.kd0'?"],
        ),
        (
            "/smm/controler_node:\n  ros__parameters:\n    fpdeso:\n      fuzzy:\n        kd0: [1.0, 1.0]\n",
            ["'/smm/controler_node'", "reaches no node", "did you mean 'controller_node'?"],
        ),
    ],
    ids=["mistyped gain", "misspelled section"],
)
def test_rerun_refuses_unknown_names_and_sections_with_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, needles: list[str]
) -> None:
    from smm_bag.cli import main
    from smm_bag.exit_codes import EXIT_USAGE

    path = tmp_path / "gains.yaml"
    path.write_text(content)
    assert main(["rerun", str(SAMPLE), "--quiet", "--params-file", str(path)]) == EXIT_USAGE
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0], captured.err
    for needle in needles:
        assert needle in lines[0], captured.err
    with pytest.raises(UnknownParameterError):
        read_params_files([path])


def test_smm_bag_rerun_refuses_a_mistyped_gain_without_a_traceback(tmp_path: Path) -> None:
    path = tmp_path / "gains.yaml"
    path.write_text("/**/controller_node:\n  ros__parameters:\n    fpdeso.fuzzy.kd00: [1.0, 1.0]\n")
    done = subprocess.run(
        [sys.executable, "-m", "smm_bag.cli", "rerun", str(SAMPLE), "--params-file", str(path)],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr and "'fpdeso.fuzzy.kd00'" in done.stderr, done.stderr
