"""ROS 2 parameter files as rcl reads them: node-key matching and precedence, without ROS."""

from __future__ import annotations

import fnmatch
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml

__all__ = [
    "ParameterFileError",
    "flat_parameters",
    "load_parameter_file",
    "node_key_matches",
    "parameters_for",
    "read_parameter_file",
    "yaml_problem",
]


class ParameterFileError(Exception):
    """A parameter file (or a ``-p`` override) is missing, malformed, or names what no node declares."""


def node_key_matches(key: str, fully_qualified_name: str) -> bool:
    """Rcl's matching of a parameter-file node key: ``/**`` spans any namespaces, ``*`` one token."""
    if key == "/**":
        return True
    pattern = key if key.startswith("/") else "/" + key
    if pattern == fully_qualified_name:
        return True
    key_tokens = pattern.strip("/").split("/")
    name_tokens = fully_qualified_name.strip("/").split("/")
    return _tokens_match(key_tokens, name_tokens)


def _tokens_match(pattern: Sequence[str], tokens: Sequence[str]) -> bool:
    if not pattern:
        return not tokens
    head, rest = pattern[0], pattern[1:]
    if head == "**":
        return any(_tokens_match(rest, tokens[skip:]) for skip in range(len(tokens) + 1))
    return bool(tokens) and fnmatch.fnmatchcase(tokens[0], head) and _tokens_match(rest, tokens[1:])


def _flatten(prefix: str, values: Mapping[str, Any], out: dict[str, Any]) -> None:
    for key, value in values.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, Mapping):
            _flatten(name, value, out)
        else:
            out[name] = value


def flat_parameters(section: Mapping[str, Any]) -> dict[str, Any]:
    """A section's ``ros__parameters`` map as ``{dotted name: value}``."""
    out: dict[str, Any] = {}
    _flatten("", section, out)
    return out


def yaml_problem(error: yaml.YAMLError) -> str:
    """A YAML error in one line: what is wrong and where (PyYAML's own message spans several)."""
    if isinstance(error, yaml.MarkedYAMLError) and error.problem_mark is not None:
        mark = error.problem_mark
        return f"{error.problem} (line {mark.line + 1}, column {mark.column + 1})"
    return " ".join(str(error).split())


def read_parameter_file(path: str | Path) -> dict[str, Mapping[str, Any]]:
    """The sections of a ROS 2 parameter file: ``{node key: ros__parameters map}``, in file order.

    Raises:
        ParameterFileError: The file is missing, is not YAML, or is not a ROS 2 parameter file.
    """
    try:
        content = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as error:
        raise ParameterFileError(f"cannot read parameter file {path}: {error}") from error
    except yaml.YAMLError as error:
        raise ParameterFileError(f"parameter file {path} is not valid YAML: {yaml_problem(error)}") from error
    if not isinstance(content, Mapping):
        raise ParameterFileError(f"parameter file {path} must map node names to sections")
    sections: dict[str, Mapping[str, Any]] = {}
    for key, section in content.items():
        if not isinstance(section, Mapping) or not isinstance(section.get("ros__parameters"), Mapping):
            raise ParameterFileError(f"parameter file {path}: section {key!r} has no 'ros__parameters' map")
        sections[str(key)] = section["ros__parameters"]
    return sections


def parameters_for(sections: Mapping[str, Mapping[str, Any]], fully_qualified_name: str) -> dict[str, Any]:
    """Parameters the sections (as :func:`read_parameter_file` gives them) set for one node, as rcl does.

    Sections are applied in file order; a wildcard section (``/**``) is applied before the sections
    that name the node, so that a node-specific value wins.

    Returns:
        ``{parameter name (dotted): value}`` (lists stay lists).
    """
    wildcard: dict[str, Any] = {}
    specific: dict[str, Any] = {}
    for key, values in sections.items():
        if node_key_matches(key, fully_qualified_name):
            (wildcard if "*" in key else specific).update(flat_parameters(values))
    return {**wildcard, **specific}


def load_parameter_file(path: str | Path, fully_qualified_name: str) -> dict[str, Any]:
    """Parameters a ROS 2 parameter file sets for one node, with rcl's precedence.

    Args:
        path: The YAML file.
        fully_qualified_name: Node name, e.g. ``/smm/smm_sim_node``.

    Returns:
        ``{parameter name (dotted): value}`` (lists stay lists).

    Raises:
        ParameterFileError: The file is missing, is not YAML, or is not a ROS 2 parameter file.
    """
    return parameters_for(read_parameter_file(path), fully_qualified_name)
