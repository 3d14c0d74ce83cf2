"""What every SMM node runs on: process main, executor, node base classes, parameters, ``/diagnostics``.

Names load on first use, so the pure modules (``parameter_files``, ``stamp_gate``, ``health``) import without
rclpy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from smm_node_runtime.admission import InputAdmission, Verdict
    from smm_node_runtime.diagnostics import (
        CountWindows,
        DiagnosticsPublisher,
        Health,
        Level,
        level_for,
        worst,
    )
    from smm_node_runtime.measurement import (
        COUNTER_ROWS,
        STAMP_PREFIX,
        WARN_COUNTERS,
        WARN_THROTTLE_S,
        ControlPeriodConfig,
        InputCounters,
        MeasurementDrivenNode,
        Output,
        values_of,
    )
    from smm_node_runtime.node import (
        NodeOptions,
        ParameterOverrides,
        SmmNode,
        as_parameter_list,
        node_arguments,
        wait_for_delivery,
    )
    from smm_node_runtime.parameter_files import (
        ParameterFileError,
        load_parameter_file,
        node_key_matches,
        parameters_for,
        read_parameter_file,
    )
    from smm_node_runtime.parameters import ConfigParameters, config_bindings
    from smm_node_runtime.process import (
        EXIT_INVALID_PARAMETER,
        EXIT_OK,
        SPIN_POLL_S,
        NodeFactory,
        ensure_localhost_discovery,
        make_executor,
        node_main,
        refused,
        run_node,
        run_nodes,
        spin_until_shutdown,
    )
    from smm_node_runtime.stamp_gate import DEFAULT_CONTROL_PERIOD, REFUSED, Admission, StampGate, StampPolicy

_SOURCES: dict[str, str] = {
    "CountWindows": "smm_node_runtime.health",
    "DiagnosticsPublisher": "smm_node_runtime.diagnostics",
    "Health": "smm_node_runtime.health",
    "Level": "smm_node_runtime.health",
    "level_for": "smm_node_runtime.health",
    "worst": "smm_node_runtime.health",
    "COUNTER_ROWS": "smm_node_runtime.admission",
    "InputAdmission": "smm_node_runtime.admission",
    "Verdict": "smm_node_runtime.admission",
    "DEFAULT_CONTROL_PERIOD": "smm_node_runtime.stamp_gate",
    "REFUSED": "smm_node_runtime.stamp_gate",
    "STAMP_PREFIX": "smm_node_runtime.measurement",
    "WARN_COUNTERS": "smm_node_runtime.measurement",
    "WARN_THROTTLE_S": "smm_node_runtime.measurement",
    "Admission": "smm_node_runtime.stamp_gate",
    "ControlPeriodConfig": "smm_node_runtime.measurement",
    "InputCounters": "smm_node_runtime.admission",
    "MeasurementDrivenNode": "smm_node_runtime.measurement",
    "Output": "smm_node_runtime.measurement",
    "StampGate": "smm_node_runtime.stamp_gate",
    "StampPolicy": "smm_node_runtime.stamp_gate",
    "values_of": "smm_node_runtime.measurement",
    "NodeOptions": "smm_node_runtime.node",
    "ParameterOverrides": "smm_node_runtime.node",
    "SmmNode": "smm_node_runtime.node",
    "as_parameter_list": "smm_node_runtime.node",
    "node_arguments": "smm_node_runtime.node",
    "wait_for_delivery": "smm_node_runtime.node",
    "ParameterFileError": "smm_node_runtime.parameter_files",
    "load_parameter_file": "smm_node_runtime.parameter_files",
    "node_key_matches": "smm_node_runtime.parameter_files",
    "parameters_for": "smm_node_runtime.parameter_files",
    "read_parameter_file": "smm_node_runtime.parameter_files",
    "ConfigParameters": "smm_node_runtime.parameters",
    "config_bindings": "smm_node_runtime.parameters",
    "EXIT_INVALID_PARAMETER": "smm_node_runtime.process",
    "EXIT_OK": "smm_node_runtime.process",
    "SPIN_POLL_S": "smm_node_runtime.process",
    "NodeFactory": "smm_node_runtime.process",
    "ensure_localhost_discovery": "smm_node_runtime.process",
    "make_executor": "smm_node_runtime.process",
    "node_main": "smm_node_runtime.process",
    "refused": "smm_node_runtime.process",
    "run_node": "smm_node_runtime.process",
    "run_nodes": "smm_node_runtime.process",
    "spin_until_shutdown": "smm_node_runtime.process",
}


def __getattr__(name: str) -> Any:
    """The exported ``name``, imported from its module on first use."""
    source = _SOURCES.get(name)
    if source is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(source), name)
    globals()[name] = value
    return value


__all__ = [
    "COUNTER_ROWS",
    "DEFAULT_CONTROL_PERIOD",
    "EXIT_INVALID_PARAMETER",
    "EXIT_OK",
    "REFUSED",
    "SPIN_POLL_S",
    "STAMP_PREFIX",
    "WARN_COUNTERS",
    "WARN_THROTTLE_S",
    "Admission",
    "ConfigParameters",
    "ControlPeriodConfig",
    "CountWindows",
    "DiagnosticsPublisher",
    "Health",
    "InputAdmission",
    "InputCounters",
    "Level",
    "MeasurementDrivenNode",
    "NodeFactory",
    "NodeOptions",
    "Output",
    "ParameterFileError",
    "ParameterOverrides",
    "SmmNode",
    "StampGate",
    "StampPolicy",
    "Verdict",
    "as_parameter_list",
    "config_bindings",
    "ensure_localhost_discovery",
    "level_for",
    "load_parameter_file",
    "make_executor",
    "node_arguments",
    "node_key_matches",
    "node_main",
    "parameters_for",
    "read_parameter_file",
    "refused",
    "run_node",
    "run_nodes",
    "spin_until_shutdown",
    "values_of",
    "wait_for_delivery",
    "worst",
]
