"""Writes docs/NODES.md's parameter tables and the nodes' known parameter names (``make parameter-tables``).

A table stands between ``<!-- parameters: <module>.<NodeClass>[; name=value, ...] -->`` and
``<!-- end of parameters -->``. The node is built in a private rclpy context (the overrides after ``;`` give
a second start, whose extra parameters are marked as declared only with them), its
``smm_node_runtime.config_bindings`` read, and each config's fields written by
``smm_schema.tables.parameter_rows``. ``tests/node_runtime/test_parameter_tables.py`` fails when the file is
out of step.

The names every node of the stack declares, under its defaults and under each read-only setting that adds
some, go to ``smm_node_runtime/known_parameters.json`` (:data:`KNOWN_NODES`), which every entry point taking a
parameter file checks names against (``smm_node_runtime.parameter_check``).

    .venv/bin/python tools/parameter_tables.py [--check]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import re
import sys
import tempfile
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.signals import SignalHandlerOptions
from smm_node_runtime.parameter_check import KNOWN_PARAMETERS_FILE, is_ros_parameter
from smm_node_runtime.parameters import config_bindings
from smm_schema.fields import parameter_name
from smm_schema.tables import TABLE_HEAD, parameter_rows

DOC = Path(__file__).resolve().parents[1] / "docs" / "NODES.md"
KNOWN_NODES: dict[str, tuple[str, tuple[tuple[str, str], ...]]] = {
    "smm_sim_node": ("smm_sim.sim_node.SimNode", ()),
    "hw_bridge_node": ("smm_hw_bridge.bridge_node.HwBridgeNode", ()),
    "reference_node": ("smm_controller.reference_node.ReferenceNode", ()),
    "td_node": ("smm_controller.td_node.TdNode", ()),
    "fleso_node": ("smm_controller.fleso_node.FlesoNode", ()),
    "controller_node": (
        "smm_controller.controller_node.ControllerNode",
        (("chain", "internal"), ("reference_source", "internal")),
    ),
    "recorder_node": ("smm_bag.recorder_node.RecorderNode", ()),
}
"""Node name -> (class, the read-only settings under which it declares more parameters)."""
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


def _declared(context: Any, node_path: str, overrides: dict[str, Any]) -> set[str]:
    """The names a node of class ``node_path`` declares under ``overrides`` (ROS's own left out)."""
    module_name, _, class_name = node_path.rpartition(".")
    node = getattr(importlib.import_module(module_name), class_name)(
        context=context, parameter_overrides=overrides
    )
    try:
        return {name for name in node.list_parameters([], 0).names if not is_ros_parameter(name)}
    finally:
        node.destroy_node()


def _direct_bridge_names(context: Any) -> set[str]:
    """The names ``direct_loop``'s bridge declares (its ``loop.*`` besides the bridge's own)."""
    from smm_direct_loop.host import compose  # noqa: PLC0415

    controller, bridge = compose(context, {"chain": "internal", "reference_source": "internal"}, {})
    try:
        return {name for name in bridge.list_parameters([], 0).names if not is_ros_parameter(name)}
    finally:
        bridge.destroy_node()
        controller.destroy_node()  # type: ignore[no-untyped-call]


def known_parameters(context: Any) -> dict[str, dict[str, list[str]]]:
    """``{node name: {"": names under its defaults, "setting=value": names it adds with it}}``.

    ``hw_bridge_node`` holds the direct loop's bridge's names too (the same node name in ``direct_loop``).
    """
    known: dict[str, dict[str, list[str]]] = {}
    with tempfile.TemporaryDirectory() as folder:
        for node_name, (node_path, settings) in KNOWN_NODES.items():
            base_overrides = {"output": str(Path(folder) / "bag")} if node_name == "recorder_node" else {}
            base = _declared(context, node_path, base_overrides)
            if node_name == "hw_bridge_node":
                base |= _direct_bridge_names(context)
            known[node_name] = {"": sorted(base)}
            for setting, value in settings:
                extra = _declared(context, node_path, {**base_overrides, setting: value}) - base
                known[node_name][f"{setting}={value}"] = sorted(extra)
    return known


def known_parameters_text(context: Any) -> str:
    """The text of ``known_parameters.json``."""
    return json.dumps(known_parameters(context), indent=1) + "\n"


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
        old_known = KNOWN_PARAMETERS_FILE.read_text() if KNOWN_PARAMETERS_FILE.is_file() else ""
        new_known = known_parameters_text(context)
    finally:
        context.try_shutdown()
    if arguments.check:
        print("docs/NODES.md parameter tables " + ("in step" if new == old else "out of step"))
        print(f"{KNOWN_PARAMETERS_FILE.name} " + ("in step" if new_known == old_known else "out of step"))
        return 0 if (new, new_known) == (old, old_known) else 1
    DOC.write_text(new)
    KNOWN_PARAMETERS_FILE.write_text(new_known)
    return 0


if __name__ == "__main__":
    sys.exit(main())
