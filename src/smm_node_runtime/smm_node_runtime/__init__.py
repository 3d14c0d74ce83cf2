"""What every SMM node runs on: process main, executor, node base classes, parameters, ``/diagnostics``."""

from smm_node_runtime.diagnostics import DiagnosticsPublisher, Health, Level, level_for
from smm_node_runtime.measurement import (
    COUNTER_ROWS,
    DEFAULT_CONTROL_PERIOD,
    WARN_THROTTLE_S,
    Admission,
    ControlPeriodConfig,
    InputCounters,
    MeasurementDrivenNode,
    Output,
    StampGate,
)
from smm_node_runtime.node import NodeOptions, ParameterOverrides, SmmNode, as_parameter_list, node_arguments
from smm_node_runtime.parameters import ConfigParameters, config_fields, parameter_name
from smm_node_runtime.process import (
    EXIT_INVALID_PARAMETER,
    EXIT_OK,
    SPIN_POLL_S,
    NodeFactory,
    ensure_localhost_discovery,
    make_executor,
    node_main,
    run_node,
    run_nodes,
    spin_until_shutdown,
)

__all__ = [
    "COUNTER_ROWS",
    "DEFAULT_CONTROL_PERIOD",
    "EXIT_INVALID_PARAMETER",
    "EXIT_OK",
    "SPIN_POLL_S",
    "WARN_THROTTLE_S",
    "Admission",
    "ConfigParameters",
    "ControlPeriodConfig",
    "DiagnosticsPublisher",
    "Health",
    "InputCounters",
    "Level",
    "MeasurementDrivenNode",
    "NodeFactory",
    "NodeOptions",
    "Output",
    "ParameterOverrides",
    "SmmNode",
    "StampGate",
    "as_parameter_list",
    "config_fields",
    "ensure_localhost_discovery",
    "level_for",
    "make_executor",
    "node_arguments",
    "node_main",
    "parameter_name",
    "run_node",
    "run_nodes",
    "spin_until_shutdown",
]
