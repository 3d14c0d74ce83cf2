"""The one constructor signature of every SMM node (:class:`NodeOptions`) and their base class."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, TypedDict, Unpack

from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.node import Node
from rclpy.parameter import Parameter

__all__ = [
    "NodeOptions",
    "ParameterOverrides",
    "SmmNode",
    "as_parameter_list",
    "node_arguments",
    "wait_for_delivery",
]

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

    def _check_undeclared_parameters(self, parameter_list: list[Parameter]) -> None:
        """Refuse undeclared names, naming them (rclpy's own check exhausts a generator and names none)."""
        if not all(isinstance(parameter, Parameter) for parameter in parameter_list):
            raise TypeError(f"parameter must be instance of type {Parameter!r}")
        undeclared = [p.name for p in parameter_list if not self.has_parameter(p.name)]
        if undeclared and not self._allow_undeclared_parameters:
            raise ParameterNotDeclaredException(undeclared)


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


def wait_for_delivery(node: Node, timeout_s: float) -> list[str]:
    """Wait until every matched reliable reader acknowledged what ``node`` published; at most ``timeout_s``.

    A node about to exit calls it: its writers go with the process, so a reader still waiting for a repair
    (a lost sample is resent at the writer's next heartbeat) would never get the rest.

    Returns:
        The topics still not acknowledged when the time was up.
    """
    deadline = time.monotonic() + timeout_s
    pending = []
    for publisher in list(node.publishers):
        remaining_ns = max(0, int((deadline - time.monotonic()) * 1e9))
        if not publisher.wait_for_all_acked(Duration(nanoseconds=remaining_ns)):
            pending.append(publisher.topic_name)
    return pending
