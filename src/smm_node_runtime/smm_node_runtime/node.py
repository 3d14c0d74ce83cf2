"""The one constructor signature of every SMM node (:class:`NodeOptions`) and their base class."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, TypedDict, Unpack

from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter

__all__ = ["NodeOptions", "ParameterOverrides", "SmmNode", "as_parameter_list", "node_arguments"]

ParameterOverrides = Sequence[Parameter] | Mapping[str, Any]
"""Parameter overrides for a node: ``rclpy.parameter.Parameter`` objects or ``{name: value}``."""


class NodeOptions(TypedDict, total=False):
    """Keyword arguments every SMM node class takes (all optional).

    Attributes:
        context: rclpy context (None: the default one); lets a launcher compose nodes in one process and
            tests use a private context.
        parameter_overrides: Values overriding the declared defaults and parameter files (see
            :func:`as_parameter_list`).
        namespace: Node namespace (None: from the command line, else the root).
        cli_args: Node-specific command-line arguments (as ``rclpy.node.Node``).
        node_name: Node name (None: the class's ``NODE_NAME``).
    """

    context: Context | None
    parameter_overrides: ParameterOverrides | None
    namespace: str | None
    cli_args: Sequence[str] | None
    node_name: str | None


def node_arguments(default_name: str, options: NodeOptions) -> tuple[str, dict[str, Any]]:
    """``(node_name, keyword arguments)`` for ``rclpy.node.Node`` (or ``LifecycleNode``) from ``options``."""
    cli_args = options.get("cli_args")
    return options.get("node_name") or default_name, {
        "context": options.get("context"),
        "parameter_overrides": as_parameter_list(options.get("parameter_overrides")),
        "namespace": options.get("namespace"),
        "cli_args": None if cli_args is None else list(cli_args),
    }


class SmmNode(Node):
    """Base class of the stack's nodes: ``Node`` built from :class:`NodeOptions`."""

    NODE_NAME: ClassVar[str]
    """Default node name, also the console script's name."""

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        name, arguments = node_arguments(getattr(type(self), "NODE_NAME", ""), options)
        if not name:
            raise TypeError(f"{type(self).__name__} needs node_name: the class sets no NODE_NAME")
        super().__init__(name, **arguments)


def as_parameter_list(overrides: ParameterOverrides | None) -> list[Parameter] | None:
    """Normalise parameter overrides to what ``rclpy.node.Node`` takes.

    Args:
        overrides: ``Parameter`` objects, or ``{name: value}`` (the value's Python type gives the ROS type,
            as a parameter file does: ``[1, 2]`` is an integer array, ``[1.0, 2.0]`` a double array).

    Returns:
        A list of ``Parameter``, or None for None.
    """
    if overrides is None:
        return None
    if isinstance(overrides, Mapping):
        return [
            Parameter(name, value=_parameter_value(value))  # type: ignore[no-untyped-call]
            for name, value in overrides.items()
        ]
    return list(overrides)


def _parameter_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value
