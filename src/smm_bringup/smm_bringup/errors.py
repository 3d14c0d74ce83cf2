"""The errors of smm_bringup: the graph cannot be described or started as asked."""

from __future__ import annotations

from smm_node_runtime import parameter_files

__all__ = ["GraphError", "ParameterFileError", "PlantNotAvailableError"]


class GraphError(Exception):
    """Base class: the graph cannot be described or started as asked."""


class PlantNotAvailableError(GraphError):
    """The chosen plant cannot run as asked (``hardware`` runs on the board's clock: real time only)."""


class ParameterFileError(GraphError, parameter_files.ParameterFileError):
    """A parameter file is missing or is not a valid ROS 2 parameter file."""
