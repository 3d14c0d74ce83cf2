"""ROS 2 parameters files written from flat parameter values (what ``--params-file`` takes as it is)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from smm_analysis.errors import AnalysisError

__all__ = ["ParametersFileError", "parameters_document", "write_parameters_file"]


class ParametersFileError(AnalysisError):
    """A value cannot be written as a ROS parameter (non-finite, empty list, mixed or unknown type)."""


def _parameter_value(name: str, value: object) -> bool | int | float | str | list[Any]:
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ParametersFileError(f"{name}: {value!r} is not a finite number")
        return value
    if isinstance(value, (Sequence, np.ndarray)):
        items = [_parameter_value(name, item) for item in value]
        if not items:
            raise ParametersFileError(f"{name}: an empty list has no ROS parameter type")
        if any(isinstance(item, list) for item in items):
            raise ParametersFileError(f"{name}: nested lists are not ROS parameters")
        if all(isinstance(item, (int, float)) and not isinstance(item, bool) for item in items):
            if any(isinstance(item, float) for item in items):
                return [float(item) for item in items if isinstance(item, (int, float))]  # doubles
            return items
        if len({type(item) for item in items}) != 1:
            raise ParametersFileError(f"{name}: mixed types {items!r}")
        return items
    raise ParametersFileError(f"{name}: {type(value).__name__} is not a ROS parameter type")


def parameters_document(sections: Mapping[str, Mapping[str, object]]) -> dict[str, Any]:
    """``{node key: {"ros__parameters": nested}}`` from ``{node key: {dotted name: value}}``.

    Raises:
        ParametersFileError: A value is not a ROS parameter, or a name is both a value and a prefix.
    """
    document: dict[str, Any] = {}
    for key, values in sections.items():
        root: dict[str, Any] = {}
        for name in sorted(values):
            *parents, leaf = name.split(".")
            if not all(parents) or not leaf:
                raise ParametersFileError(f"{key}: {name!r} is not a parameter name")
            node = root
            for part in parents:
                child = node.setdefault(part, {})
                if not isinstance(child, dict):
                    raise ParametersFileError(f"{key}: {name!r} extends the parameter {part!r}")
                node = child
            if leaf in node:
                raise ParametersFileError(f"{key}: {name!r} is both a parameter and a prefix")
            node[leaf] = _parameter_value(name, values[name])
        document[key] = {"ros__parameters": root}
    return document


def write_parameters_file(
    path: Path, sections: Mapping[str, Mapping[str, object]], comment: str = ""
) -> Path:
    """Write a parameters file, e.g. ``{"/**/controller_node": {"model.I11": 0.05}}``; returns ``path``.

    ``comment`` (may span lines) goes at the top as YAML comments.

    Raises:
        ParametersFileError: As :func:`parameters_document`.
    """
    text = yaml.safe_dump(parameters_document(sections), sort_keys=False, default_flow_style=None)
    header = "".join(f"# {line}\n" if line else "#\n" for line in comment.splitlines())
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(header + text, encoding="utf-8")
    return path
