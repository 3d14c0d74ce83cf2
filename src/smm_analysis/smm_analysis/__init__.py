"""Offline closed-loop reproduction of the FPDESO paper, metrics and bag analysis.

The package root re-exports the library (no matplotlib import); ``smm_analysis.reproduction.plots`` and
``smm_analysis.reproduction.cli`` load matplotlib.
"""

from smm_analysis.closed_loop import (
    DEFAULT_CONTROL_PERIOD,
    DEFAULT_SUBSTEPS,
    Trajectory,
    run_closed_loop,
    scenario_plant_config,
)
from smm_analysis.errors import (
    AnalysisError,
    ClosedLoopDivergedError,
    MetricsInputError,
    UnknownControllerError,
    UnknownScenarioError,
)
from smm_analysis.metrics import (
    AxisError,
    JointIndices,
    StepMetrics,
    control_energy,
    end_effector_errors,
    joint_indices,
    max_abs_error,
    mean_abs_error,
    rms_error,
    step_metrics,
    torque_increment_rms,
    validated_time,
)
from smm_analysis.scenarios import SCENARIOS, Scenario, get_scenario

__all__ = [
    "DEFAULT_CONTROL_PERIOD",
    "DEFAULT_SUBSTEPS",
    "SCENARIOS",
    "AnalysisError",
    "AxisError",
    "ClosedLoopDivergedError",
    "JointIndices",
    "MetricsInputError",
    "Scenario",
    "StepMetrics",
    "Trajectory",
    "UnknownControllerError",
    "UnknownScenarioError",
    "control_energy",
    "end_effector_errors",
    "get_scenario",
    "joint_indices",
    "max_abs_error",
    "mean_abs_error",
    "rms_error",
    "run_closed_loop",
    "scenario_plant_config",
    "step_metrics",
    "torque_increment_rms",
    "validated_time",
]
