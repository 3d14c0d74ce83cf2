"""docs/NODES.md's parameter tables are what the nodes bind (``make parameter-tables`` writes them)."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
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
