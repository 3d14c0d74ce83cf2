"""ROS 2 parameter files and values for the launch: package data files, rcl's reading, ``-p`` formatting."""

from __future__ import annotations

import contextlib
import importlib
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

from smm_bringup.errors import ParameterFileError
from smm_node_runtime import parameter_files

__all__ = ["ParameterValue", "format_parameter_value", "load_parameter_file", "node_settings", "package_file"]

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


def load_parameter_file(path: str | Path, fully_qualified_name: str) -> dict[str, Any]:
    """:func:`smm_node_runtime.parameter_files.load_parameter_file`, failing with a :class:`GraphError`.

    Raises:
        ParameterFileError: The file is missing, is not YAML, or is not a ROS 2 parameter file.
    """
    try:
        return parameter_files.load_parameter_file(path, fully_qualified_name)
    except parameter_files.ParameterFileError as error:
        raise ParameterFileError(str(error)) from error


def node_settings(files: Sequence[str | Path], fully_qualified_name: str) -> dict[str, Any]:
    """What the parameter ``files`` set for one node, later files winning (:func:`load_parameter_file`)."""
    values: dict[str, Any] = {}
    for path in files:
        values.update(load_parameter_file(path, fully_qualified_name))
    return values
