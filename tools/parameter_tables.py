"""Writes the parameter tables of docs/NODES.md from the configs each node binds (``make parameter-tables``).

A table stands between ``<!-- parameters: <module>.<NodeClass>[; name=value, ...] -->`` and
``<!-- end of parameters -->``. The node is built in a private rclpy context (the overrides after ``;`` give
a second start, whose extra parameters are marked as declared only with them), its
``smm_node_runtime.config_bindings`` read, and each config's fields written by
``smm_schema.tables.parameter_rows``. ``tests/node_runtime/test_parameter_tables.py`` fails when the file is
out of step.

    .venv/bin/python tools/parameter_tables.py [--check]
"""

from __future__ import annotations

import argparse
import importlib
import os
import re
import sys
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.signals import SignalHandlerOptions
from smm_node_runtime.parameters import config_bindings
from smm_schema.fields import parameter_name
from smm_schema.tables import TABLE_HEAD, parameter_rows

DOC = Path(__file__).resolve().parents[1] / "docs" / "NODES.md"
TABLE = re.compile(
    r"(<!-- parameters: (?P<spec>[^>]*?) -->\n)(?P<body>.*?)(<!-- end of parameters -->)",
    re.S,
)


def _value(text: str) -> Any:
    """A marker's override value: bool, int, float or string as written."""
    lowered = text.lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _node_rows(
    context: Any, node_path: str, overrides: dict[str, Any], note: str, known: set[str]
) -> list[str]:
    """The rows of the parameters the node declares under ``overrides`` that are not in ``known``."""
    module_name, _, class_name = node_path.rpartition(".")
    node_class = getattr(importlib.import_module(module_name), class_name)
    node = node_class(context=context, parameter_overrides=overrides)
    try:
        rows = []
        for binding in config_bindings(node):
            names = [parameter_name(binding.prefix, item.name) for item in binding.fields]
            fresh = [name not in known for name in names]
            made = parameter_rows(binding.prefix, binding.default, read_only=binding.read_only, note=note)
            rows += [row for row, new in zip(made, fresh, strict=True) if new]
            known.update(names)
        return rows
    finally:
        node.destroy_node()


def table(context: Any, spec: str) -> str:
    """The table a marker's ``spec`` names (head and rows, newline-terminated)."""
    node_path, _, variant = (part.strip() for part in spec.partition(";"))
    known: set[str] = set()
    rows = _node_rows(context, node_path, {}, "", known)
    if variant:
        pairs = (item.split("=") for item in variant.split(","))
        overrides = {key.strip(): _value(value.strip()) for key, value in pairs}
        note = "with " + ", ".join(f"{k}: {v}" for k, v in overrides.items()) + " only."
        rows += _node_rows(context, node_path, overrides, note, known)
    return "\n".join([TABLE_HEAD, *rows]) + "\n"


def render(text: str, context: Any) -> str:
    """``text`` with every marked table written anew."""
    return TABLE.sub(lambda m: m.group(1) + table(context, m.group("spec")) + m.group(4), text)


def main(argv: list[str] | None = None) -> int:
    """Rewrite docs/NODES.md's tables (``--check``: exit 1 when they are out of step, write nothing)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true")
    arguments = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        old = DOC.read_text()
        new = render(old, context)
    finally:
        context.try_shutdown()
    if arguments.check:
        print("docs/NODES.md parameter tables " + ("in step" if new == old else "out of step"))
        return 0 if new == old else 1
    DOC.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
