"""ROS 2 parameter files and values as rcl reads them: node-key matching, precedence, ``-p`` formatting."""

from __future__ import annotations

import contextlib
import fnmatch
import importlib
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import yaml
from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

from smm_bringup.errors import ParameterFileError

__all__ = ["ParameterValue", "format_parameter_value", "load_parameter_file", "package_file"]

ParameterValue = (
    bool | int | float | str | tuple[bool, ...] | tuple[int, ...] | tuple[float, ...] | tuple[str, ...]
)
"""A ROS parameter value as the graph description holds it (lists as tuples so specs stay hashable)."""


def format_parameter_value(value: ParameterValue) -> str:
    """Format a value for ``-p name:=value`` so that ROS parses it back with the same type.

    ROS reads the value as YAML: JSON is valid YAML flow syntax, a float keeps its decimal point
    (``1.0`` stays a double, not an integer) and a string is quoted (``"1"`` stays a string).

    Raises:
        ValueError: A non-finite float (YAML has no portable spelling that rcl accepts) or an
            unsupported type.
    """
    if isinstance(value, tuple):
        return "[" + ", ".join(format_parameter_value(item) for item in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"cannot pass a non-finite parameter value {value!r} on the command line")
        text = repr(value)
        # YAML 1.1 reads "5e-09" as a string; "5.0e-09" is a float to every YAML parser.
        mantissa, exponent_mark, exponent = text.partition("e")
        if exponent_mark and "." not in mantissa:
            text = f"{mantissa}.0e{exponent}"
        return text
    if isinstance(value, str):
        return json.dumps(value)
    raise ValueError(f"unsupported parameter value {value!r} of type {type(value).__name__}")


def package_file(package: str, relative: str) -> Path:
    """Locate a data file of a package: installed share directory first, then the source tree.

    A colcon install puts ``config/`` and ``launch/`` under ``share/<package>/`` (found through the
    ament index); an editable pip install leaves them beside the package's source directory.

    Args:
        package: Package name, e.g. ``"smm_sim"``.
        relative: Path inside the package's share directory, e.g. ``"config/scenario_case2.yaml"``.

    Raises:
        ParameterFileError: The file exists in neither place.
    """
    candidates: list[Path] = []
    # OSError: no AMENT_PREFIX_PATH at all (plain virtual environment).
    with contextlib.suppress(PackageNotFoundError, OSError):
        candidates.append(Path(get_package_share_directory(package)) / relative)
    try:
        module = importlib.import_module(package)
    except ImportError:
        pass
    else:
        if module.__file__ is not None:
            candidates.append(Path(module.__file__).resolve().parent.parent / relative)
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    tried = ", ".join(str(path) for path in candidates) or "nowhere (package not importable)"
    raise ParameterFileError(f"{package}/{relative} not found; looked in {tried}")


def _node_key_matches(key: str, fully_qualified_name: str) -> bool:
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


def load_parameter_file(path: str | Path, fully_qualified_name: str) -> dict[str, Any]:
    """Parameters a ROS 2 parameter file sets for one node, with rcl's precedence.

    Sections are applied in file order; a wildcard section (``/**``) is applied before the sections
    that name the node, so that a node-specific value wins, as rcl does.

    Args:
        path: The YAML file.
        fully_qualified_name: Node name, e.g. ``/smm/smm_sim_node``.

    Returns:
        ``{parameter name (dotted): value}`` (lists stay lists).

    Raises:
        ParameterFileError: The file is missing, is not YAML, or is not a ROS 2 parameter file.
    """
    try:
        content = yaml.safe_load(Path(path).read_text())
    except OSError as error:
        raise ParameterFileError(f"cannot read parameter file {path}: {error}") from error
    except yaml.YAMLError as error:
        raise ParameterFileError(f"parameter file {path} is not valid YAML: {error}") from error
    if not isinstance(content, Mapping):
        raise ParameterFileError(f"parameter file {path} must map node names to sections")
    wildcard: dict[str, Any] = {}
    specific: dict[str, Any] = {}
    for key, section in content.items():
        if not isinstance(section, Mapping) or not isinstance(section.get("ros__parameters"), Mapping):
            raise ParameterFileError(f"parameter file {path}: section {key!r} has no 'ros__parameters' map")
        if not _node_key_matches(str(key), fully_qualified_name):
            continue
        _flatten("", section["ros__parameters"], wildcard if "*" in str(key) else specific)
    return {**wildcard, **specific}
