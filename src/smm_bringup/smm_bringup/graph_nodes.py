"""The nodes of the SMM graph: their names, how one is started (:class:`NodeSpec`), what specs imply.

:func:`parameter_overrides` gives composed mode a spec's parameter values; :func:`expected_publishers`
gives the recorder's start gate the publishers a graph's specs bring (docs/LAUNCH.md, docs/BAGS.md).
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

from smm_bringup.errors import ParameterFileError
from smm_bringup.parameter_files import ParameterValue, format_parameter_value, node_settings
from smm_msgs_py import topics
from smm_node_runtime import parameter_check, parameter_files

__all__ = [
    "CONTROLLER_NODE",
    "DIRECT_LOOP",
    "EMULATOR_NODE",
    "FLESO_NODE",
    "HW_NODE",
    "NAMESPACE",
    "PLANT_NODE_NAMES",
    "RECORDER_NODE",
    "REFERENCE_NODE",
    "RUN_ENDERS",
    "SIM_NODE",
    "TD_NODE",
    "NodeSpec",
    "check_parameters",
    "expected_publishers",
    "parameter_overrides",
]

NAMESPACE: Final[str] = "smm"
"""Namespace of every node of the graph (topics resolve to ``/smm/<topic>``)."""

SIM_NODE: Final[str] = "smm_sim_node"
HW_NODE: Final[str] = "hw_bridge_node"
EMULATOR_NODE: Final[str] = "smm_bench_emulator"
TD_NODE: Final[str] = "td_node"
FLESO_NODE: Final[str] = "fleso_node"
REFERENCE_NODE: Final[str] = "reference_node"
CONTROLLER_NODE: Final[str] = "controller_node"
RECORDER_NODE: Final[str] = "recorder_node"
DIRECT_LOOP: Final[str] = "direct_loop"
"""The direct loop's process (console script of ``smm_direct_loop``), hosting HW_NODE and CONTROLLER_NODE."""

PLANT_NODE_NAMES: Final[frozenset[str]] = frozenset((SIM_NODE, HW_NODE, EMULATOR_NODE))
"""Names of the plant processes: when one of them exits 0 the run is complete (see ``docs/LAUNCH.md``);
with the emulator that is the end of its ``duration``."""

RUN_ENDERS: Final[frozenset[str]] = PLANT_NODE_NAMES | {DIRECT_LOOP}
"""Processes whose exit 0 completes the run: the plants, and the direct loop hosting the bridge (which ends
an external board's run after its ``--duration``, ``verdict.ends_run``)."""

_PUBLISHED: Final[dict[str, tuple[str, ...]]] = {
    CONTROLLER_NODE: (topics.TORQUE_COMMAND, topics.CONTROLLER_INTERNALS),
    TD_NODE: (topics.JOINT_STATES_FILTERED,),
    FLESO_NODE: (topics.DISTURBANCE_ESTIMATE, topics.OBSERVER_STATE),
    REFERENCE_NODE: (topics.REFERENCE,),
    DIRECT_LOOP: (
        topics.TORQUE_COMMAND,
        topics.CONTROLLER_INTERNALS,
        topics.JOINT_STATES,
        topics.HW_BRIDGE_INTERNALS,
    ),
}
"""The recorded stack topics each controller-side node publishes (besides ``/diagnostics``)."""


@dataclass(frozen=True)
class NodeSpec:
    """One node of the graph.

    Attributes:
        package: ROS package that provides the executable.
        executable: Console script (``ros2 run <package> <executable>``).
        name: Node name (``-r __node:=<name>``).
        namespace: Node namespace without slashes (``-r __ns:=/<namespace>``).
        node_class: ``"module:Class"`` of the rclpy node, for composed mode.
        parameter_files: ROS 2 parameter files, lowest precedence first.
        parameters: Parameter overrides ``(name, value)``, applied after the files.
        remappings: Topic remappings ``(from, to)``.
        rt_priority: SCHED_FIFO priority of the process (1-99); 0: normal scheduling.
        hosts: Names of the nodes a process hosts when it hosts several (the direct loop): they keep their
            own names (no ``__node`` remapping), the parameter files apply to each by its name, and every
            node takes from :attr:`parameters` the names it declares.
    """

    package: str
    executable: str
    name: str
    node_class: str
    namespace: str = NAMESPACE
    parameter_files: tuple[str, ...] = ()
    parameters: tuple[tuple[str, ParameterValue], ...] = ()
    remappings: tuple[tuple[str, str], ...] = ()
    rt_priority: int = 0
    hosts: tuple[str, ...] = ()

    @property
    def fully_qualified_name(self) -> str:
        """Absolute node name, e.g. ``/smm/smm_sim_node``."""
        return f"/{self.namespace}/{self.name}" if self.namespace else f"/{self.name}"

    def ros_arguments(self) -> list[str]:
        """The ``--ros-args`` part of the command line (the same as ``ros2 launch`` would pass).

        Returns:
            ``["--ros-args", "-r", "__ns:=/smm", "-r", "__node:=<name>", "--params-file", F, ...,
            "-p", "key:=value", ..., "-r", "from:=to", ...]``.
        """
        namespace = f"/{self.namespace}" if self.namespace else "/"
        arguments = ["--ros-args", "-r", f"__ns:={namespace}"]
        if not self.hosts:
            arguments += ["-r", f"__node:={self.name}"]
        for path in self.parameter_files:
            arguments += ["--params-file", path]
        for name, value in self.parameters:
            arguments += ["-p", f"{name}:={format_parameter_value(value)}"]
        for source, target in self.remappings:
            arguments += ["-r", f"{source}:={target}"]
        return arguments

    def command_line(self, executable_path: str) -> list[str]:
        """Full argv to start this node as its own process.

        Args:
            executable_path: Resolved path of :attr:`executable`.
        """
        return [executable_path, *self.ros_arguments()]

    def load_class(self) -> type[Any]:
        """Import and return the node class (composed mode)."""
        module_name, _, class_name = self.node_class.partition(":")
        node_type: type[Any] = getattr(importlib.import_module(module_name), class_name)
        return node_type


def expected_publishers(specs: Sequence[NodeSpec]) -> dict[str, int]:
    """Publishers a recorder must have matched per topic before the plant of ``specs`` starts stepping.

    Counts the controller-side nodes' stack topics (absolute names) and one ``/diagnostics`` publisher each.
    """
    counts: dict[str, int] = {}
    for spec in specs:
        if spec.name not in _PUBLISHED:
            continue
        published = _PUBLISHED[spec.name]
        if ("reference_source", "internal") in spec.parameters:
            published = (*published, topics.REFERENCE)
        for topic in (topics.fully_qualified(name, spec.namespace) for name in published):
            counts[topic] = counts.get(topic, 0) + 1
        counts["/diagnostics"] = counts.get("/diagnostics", 0) + max(1, len(spec.hosts))
    return counts


def parameter_overrides(spec: NodeSpec) -> dict[str, Any]:
    """All parameter values the spec sets for its node, files first, then the explicit overrides.

    This is what the separate-process command line makes rcl compute; composed mode passes it to the
    node class as ``parameter_overrides``.
    """
    values = node_settings(spec.parameter_files, spec.fully_qualified_name)
    for name, value in spec.parameters:
        values[name] = list(value) if isinstance(value, tuple) else value
    return values


def check_parameters(spec: NodeSpec) -> None:
    """Refuse the unknown names and sections of ``spec``'s files and overrides, as its process would.

    :func:`smm_node_runtime.parameter_check.check_parameters`; a process that is not a node of the stack
    (the bench emulator) is not checked.

    Raises:
        ParameterFileError: A file is missing or malformed, a section reaches no node, a name is unknown.
    """
    names = spec.hosts or ((spec.name,) if spec.name in parameter_check.known_nodes() else ())
    if not names:
        return
    running = {parameter_check.fully_qualified(spec.namespace, name): name for name in names}
    overrides = [
        parameter_check.Override(
            name,
            list(value) if isinstance(value, tuple) else value,
            text=f"{name}:={format_parameter_value(value)}",
        )
        for name, value in spec.parameters
    ]
    try:
        parameter_check.check_parameters(spec.parameter_files, overrides, running, spec.namespace)
    except parameter_files.ParameterFileError as error:
        raise ParameterFileError(str(error)) from error
