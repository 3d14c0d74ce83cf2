"""docs/NODES.md's parameter tables and ``known_parameters.json`` are what the nodes bind and declare
(``make parameter-tables`` writes them)."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from smm_node_runtime.parameter_check import KNOWN_PARAMETERS_FILE, is_ros_parameter
from smm_schema.ranges import above, at_least, check_bounds
from smm_schema.tables import TABLE_HEAD, parameter_rows

REPO = Path(__file__).resolve().parents[2]


def _generator() -> ModuleType:
    spec = importlib.util.spec_from_file_location("parameter_tables", REPO / "tools" / "parameter_tables.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.ros
def test_docs_nodes_md_tables_are_in_step_with_the_nodes(ros_context: Any) -> None:
    generator = _generator()
    text = generator.DOC.read_text()
    assert text.count("<!-- parameters: ") >= 5
    assert generator.render(text, ros_context) == text, "run: make parameter-tables"


@pytest.mark.ros
def test_the_known_parameter_names_are_in_step_with_the_nodes(ros_context: Any) -> None:
    text = _generator().known_parameters_text(ros_context)
    assert text == KNOWN_PARAMETERS_FILE.read_text(), "run: make parameter-tables"


@pytest.mark.ros
def test_what_rclpy_declares_on_a_bare_node_is_rosown(ros_context: Any) -> None:
    import rclpy
    from rclpy.qos_overriding_options import QoSOverridingOptions
    from std_msgs.msg import Empty

    node = rclpy.create_node("bare", context=ros_context)
    try:
        node.create_publisher(
            Empty, "t", 1, qos_overriding_options=QoSOverridingOptions.with_default_policies()
        )
        names = node.list_parameters([], 0).names
    finally:
        node.destroy_node()
    assert {"use_sim_time", "start_type_description_service"} <= set(names)
    assert any(name.startswith("qos_overrides.") for name in names)
    assert all(is_ros_parameter(name) for name in names), names


def test_a_row_names_type_default_range_and_meaning() -> None:
    from dataclasses import dataclass, field

    @dataclass(frozen=True)
    class Probe:
        """A probe.

        Attributes:
            gain: Per joint (1/s) | scaled.
            count: How many.
        """

        gain: tuple[float, float] = field(default=(1.5, 2.0), metadata=above(0.0))
        count: int = field(default=3, metadata=at_least(3))

        def __post_init__(self) -> None:
            check_bounds(self)

    rows = parameter_rows("probe", Probe(), read_only=True, note="internal only.")
    assert TABLE_HEAD.startswith("| parameter | type | default | range | meaning |")
    assert rows == [
        "| `probe.gain` | double[2] | [1.5, 2] | each > 0 | "
        "*internal only.* Per joint (1/s) \\| scaled. Read-only. |",
        "| `probe.count` | integer | 3 | >= 3 | *internal only.* How many. Read-only. |",
    ]


def test_an_edited_table_is_found_out_of_step() -> None:
    generator = _generator()
    text = "<!-- parameters: x.Y -->\n| stale |\n<!-- end of parameters -->\n"
    generator.table = lambda context, spec: f"{TABLE_HEAD}\n| `{spec}` |\n"
    assert generator.render(text, None) != text
    assert "| `x.Y` |" in generator.render(text, None)
