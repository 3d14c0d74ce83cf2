"""What every SMM node runs on: process main, executor, node base classes, parameters, ``/diagnostics``."""

from smm_node_runtime.diagnostics import DiagnosticsPublisher
from smm_node_runtime.health import CountWindows, Health, Level, level_for, worst
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
from smm_node_runtime.ranges import bounds, check_bounds
from smm_node_runtime.stamp_gate import DEFAULT_CONTROL_PERIOD, REFUSED, Admission, StampGate, StampPolicy

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
    "InputCounters",
    "Level",
    "MeasurementDrivenNode",
    "NodeFactory",
    "NodeOptions",
    "Output",
    "ParameterOverrides",
    "SmmNode",
    "StampGate",
    "StampPolicy",
    "as_parameter_list",
    "bounds",
    "check_bounds",
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
    "values_of",
    "wait_for_delivery",
    "worst",
]
