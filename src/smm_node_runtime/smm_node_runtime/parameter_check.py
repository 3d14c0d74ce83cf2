"""Refuse parameter names and node sections no node of the stack declares, before any node starts.

rcl hands a node every value a parameter file or ``-p`` sets for it, and the node silently ignores the names
it does not declare: a mistyped gain would leave the gain at its default. The names each node declares
(``known_parameters.json``, written by ``tools/parameter_tables.py`` from the configs the nodes bind) are
checked here for every entry point that takes parameter files: node executables, ``smm-launch`` and
``smm-bag rerun``. Rules: docs/LAUNCH.md, "Parameter names are checked".
"""

from __future__ import annotations

import difflib
import functools
import json
import re
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import yaml

from smm_node_runtime.parameter_files import (
    ParameterFileError,
    flat_parameters,
    node_key_matches,
    parameters_for,
    read_parameter_file,
    yaml_problem,
)

__all__ = [
    "KNOWN_PARAMETERS_FILE",
    "RENAMED",
    "ROS_PARAMETERS",
    "Override",
    "RosArguments",
    "UnknownParameterError",
    "check_node_arguments",
    "check_parameters",
    "did_you_mean",
    "fully_qualified",
    "is_ros_parameter",
    "known_names",
    "known_nodes",
    "parse_ros_arguments",
]

KNOWN_PARAMETERS_FILE: Final[Path] = Path(__file__).with_name("known_parameters.json")
"""``{node name: {"": names, "setting=value": names declared besides only with that setting}}``."""

ROS_PARAMETERS: Final[frozenset[str]] = frozenset({"use_sim_time", "start_type_description_service"})
"""Parameters rclpy itself declares on every node, allowed everywhere (besides ``qos_overrides.*``)."""
_ROS_PREFIXES: Final[tuple[str, ...]] = ("qos_overrides.",)
RENAMED: Final[Mapping[str, str]] = {"link.canopen.": "canopen."}
"""Old name prefix -> the new one: an old name is refused with its new name as the hint (issue 42)."""

_OVERRIDE = re.compile(
    r"(?:(?P<node>[A-Za-z_][A-Za-z0-9_]*):)?(?P<name>[A-Za-z0-9_]+(?:\.[A-Za-z0-9_]+)*):=(?P<value>.*)", re.S
)
"""rcl's ``-p [node:]name:=value``."""
_VALUE_FLAGS: Final[frozenset[str]] = frozenset(
    {"-r", "--remap", "-e", "--enclave", "--log-level", "--log-config-file", "--log-file-name"}
)
"""ROS flags besides ``-p`` and ``--params-file`` that take the next argument as their value."""


class UnknownParameterError(ParameterFileError):
    """A parameter file or ``-p`` sets a name that no node it reaches declares, or reaches no node."""


def is_ros_parameter(name: str) -> bool:
    """True for a parameter rclpy declares on every node (``use_sim_time``, ``qos_overrides.*``, ...)."""
    return name in ROS_PARAMETERS or name.startswith(_ROS_PREFIXES)


@functools.cache
def known_nodes() -> Mapping[str, Mapping[str, frozenset[str]]]:
    """The stack's nodes (by name) and the names each declares: ``{"": always, "setting=value": besides}``."""
    content = json.loads(KNOWN_PARAMETERS_FILE.read_text(encoding="utf-8"))
    return {node: {key: frozenset(names) for key, names in sets.items()} for node, sets in content.items()}


def known_names(node: str, values: Mapping[str, Any] | None = None) -> frozenset[str]:
    """The names ``node`` declares with the parameter ``values`` it gets (None: under any setting)."""
    names: set[str] = set()
    for key, group in known_nodes()[node].items():
        setting, _, wanted = key.partition("=")
        if not key or values is None or _as_text(values.get(setting)) == wanted:
            names |= group
    return frozenset(names)


def _as_text(value: Any) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def fully_qualified(namespace: str, name: str) -> str:
    """``/ns/name`` (``/name`` in the root namespace)."""
    stripped = namespace.strip("/")
    return f"/{stripped}/{name}" if stripped else f"/{name}"


@dataclass(frozen=True)
class Override:
    """One ``-p [node:]name:=value``: ``node`` is the node key it targets (``/**``: every node)."""

    name: str
    value: Any
    node: str = "/**"
    text: str = ""

    @property
    def where(self) -> str:
        """How an error names it: ``-p name:=value``."""
        return f"-p {self.text or self.name}"


@dataclass(frozen=True)
class RosArguments:
    """What the ``--ros-args`` of a command line set for its nodes' parameters and names."""

    files: tuple[str, ...] = ()
    overrides: tuple[Override, ...] = ()
    namespace: str = "/"
    node_name: str | None = None


def _override(text: str) -> Override:
    match = _OVERRIDE.fullmatch(text)
    if match is None:
        raise ParameterFileError(f"-p {text!r}: not a parameter override NAME:=VALUE (e.g. seed:=3)")
    try:
        value = yaml.safe_load(match["value"])
    except yaml.YAMLError as error:
        raise ParameterFileError(
            f"-p {text!r}: the value is not YAML: {yaml_problem(error)} "
            "(quote an array for the shell: -p 'name:=[1.0, 2.0]')"
        ) from None
    _check_value(value, f"-p {text!r}")
    return Override(match["name"], value, match["node"] or "/**", text)


def _check_value(value: Any, where: str) -> None:
    """Refuse what rcl refuses: no value, a map, a nested or empty list, a list mixing types (1 and 1.0)."""
    scalar = (bool, int, float, str)
    if isinstance(value, scalar):
        return
    if isinstance(value, list) and value and all(isinstance(item, scalar) for item in value):
        if len({type(item) for item in value}) == 1:
            return
        raise ParameterFileError(
            f"{where}: a list mixes types {value!r} (write 1.0, not 1, in a list of doubles)"
        )
    raise ParameterFileError(
        f"{where}: {value!r} is not a parameter value (bool, number, string or a non-empty list of one type)"
    )


def parse_ros_arguments(args: Sequence[str]) -> RosArguments:
    """The parameter files, ``-p`` overrides, namespace and node name of ``args``' ``--ros-args`` sections.

    Raises:
        ParameterFileError: A ``-p`` that is not ``[node:]name:=value`` with a YAML scalar or flat list, or a
            ``-p`` / ``--params-file`` without its argument. Files are not read here.
    """
    files: list[str] = []
    overrides: list[Override] = []
    namespace, node_name = "/", None
    inside = False
    index = 0
    while index < len(args):
        token = args[index]
        index += 1
        if token == "--ros-args":
            inside = True
            continue
        if not inside:
            continue
        if token == "--":
            inside = False
            continue
        takes_value = token in ("-p", "--param", "--params-file") or token in _VALUE_FLAGS
        if not takes_value:
            continue
        if index >= len(args):
            raise ParameterFileError(f"{token} at the end of the command line has no argument")
        value = args[index]
        index += 1
        if token in ("-p", "--param"):
            overrides.append(_override(value))
        elif token == "--params-file":
            files.append(value)
        elif token in ("-r", "--remap"):
            target, _, replacement = value.partition(":=")
            if target == "__ns":
                namespace = replacement
            elif target in ("__node", "__name"):
                node_name = replacement
    return RosArguments(tuple(files), tuple(overrides), namespace, node_name)


def check_parameters(
    files: Sequence[str | Path],
    overrides: Sequence[Override],
    running: Mapping[str, str],
    namespace: str,
) -> None:
    """Refuse a section that reaches no node and a name that no node it reaches declares.

    The stack's nodes are taken to run in ``namespace`` (so a file may hold sections for the other nodes of
    a graph); those in ``running`` are checked with the values the files and overrides give them (a name
    declared only under a setting, e.g. ``td.*`` of ``controller_node`` with ``chain: internal``, needs it),
    the others against every name they declare under any setting. A wildcard section (``/**``,
    ``/**/name``, ``/ns/*``) may set any name one of the nodes it reaches declares. ROS's own parameters
    (:func:`is_ros_parameter`) are always allowed. Overrides reach the ``running`` nodes only.

    Args:
        files: Parameter files, in order.
        overrides: ``-p`` overrides of the running nodes.
        running: ``{fully qualified name: stack node name}`` of the nodes started with them.
        namespace: Namespace of the stack's other nodes.

    Raises:
        ParameterFileError: A file is missing or malformed.
        UnknownParameterError: A section reaches no node, or a name is declared by none it reaches (the
            message names the name, the section, the file and the closest known name).
    """
    nodes = {fully_qualified(namespace, name): name for name in known_nodes()}
    nodes.update(running)
    read = [(str(path), read_parameter_file(path)) for path in files]
    values: dict[str, dict[str, Any] | None] = dict.fromkeys(nodes)
    for fqn in running:
        given: dict[str, Any] = {}
        for _, sections in read:
            given.update(parameters_for(sections, fqn))
        given.update((o.name, o.value) for o in overrides if node_key_matches(o.node, fqn))
        values[fqn] = given
    for path, sections in read:
        for key, section in sections.items():
            reached = [fqn for fqn in nodes if node_key_matches(key, fqn)]
            where = f"section '{key}' of {path}"
            if not reached:
                raise UnknownParameterError(f"{where} reaches no node{_no_node_hint(key, nodes)}")
            for name, value in flat_parameters(section).items():
                _check_value(value, f"parameter '{name}' in {where}")
                _check_name(name, where, {fqn: nodes[fqn] for fqn in reached}, values)
    for override in overrides:
        reached = [fqn for fqn in running if node_key_matches(override.node, fqn)]
        if not reached:
            raise UnknownParameterError(f"{override.where} reaches no node of {', '.join(running) or 'none'}")
        _check_name(override.name, override.where, {fqn: running[fqn] for fqn in reached}, values)


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``"; did you mean 'closest'?"``: the ``known`` name closest to ``name`` (a renamed one's new name)."""
    known = set(known)
    for old, new in RENAMED.items():
        if name.startswith(old) and new + name[len(old) :] in known:
            return f"; did you mean '{new}{name[len(old) :]}'? ({old}* is now {new}*)"
    close = difflib.get_close_matches(name, sorted(known), n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def _no_node_hint(key: str, nodes: Mapping[str, str]) -> str:
    last = key.rstrip("/").rpartition("/")[2]
    same = sorted(fqn for fqn, node in nodes.items() if last in (node, fqn.rpartition("/")[2]))
    if same:
        return f" ({last} runs as {', '.join(same)} here: another namespace?)"
    return f" (the nodes: {', '.join(sorted(nodes))}){did_you_mean(last, set(nodes.values()))}"


def _check_name(
    name: str, where: str, reached: Mapping[str, str], values: Mapping[str, Mapping[str, Any] | None]
) -> None:
    if is_ros_parameter(name):
        return
    if any(name in known_names(node, values[fqn]) for fqn, node in reached.items()):
        return
    for fqn, node in reached.items():
        for key, group in known_nodes()[node].items():
            if name in group:
                setting, _, wanted = key.partition("=")
                raise UnknownParameterError(
                    f"parameter '{name}' in {where}: {fqn} declares it only with {setting}: {wanted}"
                )
    known = set().union(*(known_names(node) for node in reached.values()))
    targets = ", ".join(sorted(reached))
    raise UnknownParameterError(
        f"unknown parameter '{name}' in {where} (no such name on {targets}){did_you_mean(name, known)}"
    )


def check_node_arguments(args: Sequence[str] | None, nodes: Iterable[str]) -> RosArguments:
    """Check a node process's command line before ``rclpy.init`` (:func:`check_parameters`).

    Args:
        args: The command line; None for ``sys.argv``.
        nodes: Names of the stack's nodes the process runs (renamed by ``-r __node:=``).

    Raises:
        ParameterFileError: As :func:`parse_ros_arguments` and :func:`check_parameters`.
    """
    arguments = parse_ros_arguments(list(sys.argv if args is None else args))
    running = {fully_qualified(arguments.namespace, arguments.node_name or node): node for node in nodes}
    check_parameters(arguments.files, arguments.overrides, running, arguments.namespace)
    return arguments
