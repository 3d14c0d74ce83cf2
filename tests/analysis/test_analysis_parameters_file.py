"""The parameters-file writer: rcl's reader (as graph.py implements it) gets back what was written."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st
from smm_analysis.parameters_file import ParametersFileError, parameters_document, write_parameters_file
from smm_bringup.parameter_files import load_parameter_file

_NAMES = st.lists(st.from_regex(r"[a-z][a-z0-9_]{0,6}", fullmatch=True), min_size=1, max_size=3).map(".".join)
_VALUES = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False),
    st.integers(-(2**62), 2**62),
    st.booleans(),
    st.text(st.characters(codec="ascii", categories=["L", "N"]), max_size=8),
    st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1, max_size=3),
)


def test_nested_sections_and_double_arrays(tmp_path: Path) -> None:
    path = write_parameters_file(
        tmp_path / "model.yaml",
        {"/**/controller_node": {"model.I11": 0.05, "model.viscous_friction": (0.1, 0), "algorithm": "pid"}},
        comment="identified\nfrom two bags",
    )
    text = path.read_text()
    assert text.startswith("# identified\n# from two bags\n")
    document = yaml.safe_load(text)
    model = document["/**/controller_node"]["ros__parameters"]["model"]
    assert model == {"I11": 0.05, "viscous_friction": [0.1, 0.0]}
    assert isinstance(model["viscous_friction"][1], float)


@given(st.dictionaries(_NAMES, _VALUES, max_size=6))
def test_round_trip_through_the_rcl_reader(values: dict[str, object]) -> None:
    prefixes = {name.rsplit(".", 1)[0] for name in values if "." in name}
    if any(name in prefixes or any(p.startswith(name + ".") for p in prefixes) for name in values):
        with pytest.raises(ParametersFileError):
            parameters_document({"/**/controller_node": values})
        return
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = write_parameters_file(Path(folder) / "p.yaml", {"/**/controller_node": values})
        read = load_parameter_file(path, "/smm/controller_node")
    expected = {k: [float(x) for x in v] if isinstance(v, list) else v for k, v in values.items()}
    assert read == expected


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        (math.nan, "finite"),
        (np.float64(math.inf), "finite"),
        ([], "empty"),
        ([[1.0]], "nested"),
        ([1.0, "a"], "mixed"),
        (object(), "not a ROS parameter type"),
    ],
)
def test_values_that_are_no_ros_parameter_are_refused(value: object, reason: str) -> None:
    with pytest.raises(ParametersFileError, match=reason):
        parameters_document({"/**/controller_node": {"model.I11": value}})


def test_a_name_cannot_be_a_value_and_a_prefix() -> None:
    with pytest.raises(ParametersFileError, match=r"prefix|extends"):
        parameters_document({"/**/controller_node": {"model": 1.0, "model.I11": 2.0}})
    with pytest.raises(ParametersFileError, match="not a parameter name"):
        parameters_document({"/**/controller_node": {"model..I11": 2.0}})
