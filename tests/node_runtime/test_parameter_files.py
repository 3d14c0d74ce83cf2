"""ROS 2 parameter files read as rcl reads them (smm_node_runtime.parameter_files, no ROS)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_node_runtime.parameter_files import (
    ParameterFileError,
    load_parameter_file,
    node_key_matches,
    parameters_for,
    read_parameter_file,
)


@pytest.mark.parametrize(
    ("key", "matches"),
    [
        ("/smm/smm_sim_node", True),
        ("smm/smm_sim_node", True),
        ("/**", True),
        ("/**/smm_sim_node", True),
        ("/*/smm_sim_node", True),
        ("/smm/*", True),
        ("/smm_sim_node", False),
        ("/other/smm_sim_node", False),
        ("/**/td_node", False),
        ("/*", False),
    ],
)
def test_node_keys_match_like_rcl(key: str, matches: bool) -> None:
    assert node_key_matches(key, "/smm/smm_sim_node") is matches


def test_sections_keep_file_order_and_nesting(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text("/b:\n  ros__parameters:\n    x: {y: 1}\n/a:\n  ros__parameters:\n    z: 2\n")
    sections = read_parameter_file(path)
    assert list(sections) == ["/b", "/a"]
    assert parameters_for(sections, "/b") == {"x.y": 1}
    assert load_parameter_file(path, "/a") == {"z": 2}
    assert load_parameter_file(path, "/c") == {}


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("- 1\n- 2\n", "must map node names"),
        ("/**:\n  params:\n    a: 1\n", "has no 'ros__parameters' map"),
        ("a: [1,\n", "not valid YAML"),
    ],
)
def test_invalid_parameter_files_say_what_is_wrong(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    with pytest.raises(ParameterFileError, match=message):
        load_parameter_file(path, "/smm/smm_sim_node")


def test_a_missing_file_is_a_parameter_file_error(tmp_path: Path) -> None:
    with pytest.raises(ParameterFileError, match="cannot read"):
        read_parameter_file(tmp_path / "absent.yaml")


_KEYS = ("/**", "/**/controller_node", "/smm/controller_node", "/other/controller_node", "/smm/*")


@given(st.permutations(range(len(_KEYS))))
def test_an_exact_key_wins_over_wildcards_in_any_order(order: list[int]) -> None:
    sections = {_KEYS[i]: {"gain": float(i), f"only_{i}": i} for i in order}
    values = parameters_for(sections, "/smm/controller_node")
    assert values["gain"] == float(_KEYS.index("/smm/controller_node"))
    assert "only_3" not in values  # another namespace's key
    assert {name for name in values if name.startswith("only_")} == {"only_0", "only_1", "only_2", "only_4"}
