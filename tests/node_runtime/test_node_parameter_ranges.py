"""Every node's parameters carry the ranges their config fields declare, and every such field declares one.

The nodes are found in the code (every ``*_node.py`` module of ``src``), and their configs through what they
declare (each :class:`ConfigParameters` binding a node makes), so a new node or config is covered unasked.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rcl_interfaces.msg import ParameterType
from rclpy.node import Node
from smm_node_runtime.parameters import ConfigParameters, parameter_descriptor
from smm_schema.fields import config_fields, parameter_name, unranged_fields
from smm_schema.ranges import above

pytestmark = pytest.mark.ros

SRC = Path(__file__).resolve().parents[2] / "src"
ROS_OWN = {"use_sim_time", "start_type_description_service"}  # declared by rclpy itself
NUMERIC_TYPES = {
    ParameterType.PARAMETER_DOUBLE,
    ParameterType.PARAMETER_INTEGER,
    ParameterType.PARAMETER_DOUBLE_ARRAY,
    ParameterType.PARAMETER_INTEGER_ARRAY,
}

VARIANTS: dict[str, list[dict[str, Any]]] = {
    "ControllerNode": [{}, {"chain": "internal", "reference_source": "internal"}],
}
"""Overrides under which a node declares more parameters (one start per entry; default: ``[{}]``)."""


def _node_classes() -> Iterator[type[Any]]:
    for path in sorted(SRC.glob("*/*/*_node.py")):
        module = importlib.import_module(f"{path.parent.name}.{path.stem}")
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, Node) and cls.__module__ == module.__name__:
                yield cls


STARTS = [
    pytest.param(cls, overrides, id=f"{cls.__name__}{index or ''}")
    for cls in _node_classes()
    for index, overrides in enumerate(VARIANTS.get(cls.__name__, [{}]))
]


@dataclass(frozen=True)
class Binding:
    """One config a node mirrors as parameters."""

    prefix: str
    config_cls: type
    read_only: bool


@pytest.fixture
def bindings(monkeypatch: pytest.MonkeyPatch) -> list[Binding]:
    """Records every ConfigParameters binding made while the test runs."""
    made: list[Binding] = []
    original = ConfigParameters.__init__

    def recording(self: Any, node: Any, prefix: str, default: Any, **options: Any) -> None:
        original(self, node, prefix, default, **options)
        made.append(Binding(prefix, type(default), bool(options.get("read_only", False))))

    monkeypatch.setattr(ConfigParameters, "__init__", recording)
    return made


def test_every_node_module_is_found() -> None:
    names = {cls.__name__ for cls in _node_classes()}
    assert {"ControllerNode", "TdNode", "FlesoNode", "ReferenceNode", "SimNode", "HwBridgeNode"} <= names
    assert "RecorderNode" in names


def range_problems(node: Any, bindings: list[Binding]) -> list[str]:
    """What is wrong with the ranges of ``node``'s parameters (empty when each mirrors its metadata)."""
    problems: list[str] = []
    bound: set[str] = set()
    for binding in bindings:
        name_of_config = binding.config_cls.__name__
        missing = unranged_fields(binding.config_cls)
        if missing:
            problems.append(f"{name_of_config}: no range declared for {list(missing)}")
        for item in config_fields(binding.config_cls):
            name = parameter_name(binding.prefix, item.name)
            bound.add(name)
            expected = parameter_descriptor(item, name, binding.read_only)
            actual = node.describe_parameter(name)
            for attribute in (
                "type",
                "additional_constraints",
                "read_only",
                "floating_point_range",
                "integer_range",
            ):
                if getattr(actual, attribute) != getattr(expected, attribute):
                    problems.append(
                        f"{name}: {attribute} {getattr(actual, attribute)} != {getattr(expected, attribute)}"
                    )
    loose = sorted(set(node.list_parameters([], 0).names) - ROS_OWN - bound)
    numeric = [name for name in loose if node.describe_parameter(name).type in NUMERIC_TYPES]
    if numeric:
        problems.append(f"numeric parameters declared outside a config, without a declared range: {numeric}")
    return problems


@pytest.mark.parametrize(("node_class", "overrides"), STARTS)
def test_every_numeric_parameter_has_its_fields_range_and_ros_shows_it(
    ros_context: Any, bindings: list[Binding], node_class: type[Any], overrides: dict[str, Any]
) -> None:
    node: Any = node_class(context=ros_context, parameter_overrides=overrides)
    try:
        assert bindings, f"{node_class.__name__} mirrors no config"
        assert range_problems(node, bindings) == []
    finally:
        node.destroy_node()


@dataclass(frozen=True)
class Planted:
    """A config with one number that forgot its range.

    Attributes:
        gain: Per joint (1/s), > 0.
        forgotten: A scalar (m), > 0 in prose only.
    """

    gain: tuple[float, float] = field(default=(1.0, 2.0), metadata=above(0.0))
    forgotten: float = 1.0


def test_a_planted_field_without_a_range_fails_the_check(ros_context: Any, bindings: list[Binding]) -> None:
    node: Any = rclpy.create_node("planted", context=ros_context)
    try:
        ConfigParameters(node, "planted", Planted())
        node.declare_parameter("loose_gain", 1.0)
        assert range_problems(node, bindings) == [
            "Planted: no range declared for ['forgotten']",
            "numeric parameters declared outside a config, without a declared range: ['loose_gain']",
        ]
    finally:
        node.destroy_node()
