"""What a reproduction produces: each run's metrics, the step study, the acceptance checks, the result."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from smm_analysis.closed_loop import Trajectory
from smm_analysis.metrics import AxisError, JointIndices, StepMetrics
from smm_analysis.scenarios import Scenario
from smm_controller import TrackingDifferentiatorConfig

__all__ = ["JOINTS", "AcceptanceCheck", "ReproductionResult", "RunResult", "StepStudyPoint"]

JOINTS: tuple[str, str] = ("alpha", "beta")


@dataclass(frozen=True)
class AcceptanceCheck:
    """One acceptance claim on one joint.

    Attributes:
        claim: What is claimed, in words.
        scenario: Scenario name.
        joint: ``alpha`` or ``beta``.
        value: The measured quantity (unit in ``claim``).
        requirement: The bound, in words.
        passed: Whether the claim holds.
        controller: The controller (gain set) the claim is checked on: ``"fpdeso"`` for the paper's
            gains, or a retuned set's name.
        quantity: What ``value`` is: ``overshoot_fraction``, ``rise_time``, ``RMS``, ``Ma``,
            ``rms_reduction`` or ``eps_u``; matches a retuned set's check with the paper set's.
    """

    claim: str
    scenario: str
    joint: str
    value: float
    requirement: str
    passed: bool
    controller: str = "fpdeso"
    quantity: str = ""


@dataclass(frozen=True, eq=False)
class RunResult:
    """Metrics of one scenario x controller run.

    Attributes:
        scenario: Scenario name.
        controller: Controller name.
        joints: Eq. 42-45 per joint (error on the true position, energy of the commanded torque).
        step: Step metrics per joint (step scenarios only).
        end_effector: End-effector errors along x, y, z (mm).
        wall_time: Wall-clock time of the run (s), for the progress line only.
        trajectory: The sampled run (for plots).
    """

    scenario: str
    controller: str
    joints: Mapping[str, JointIndices]
    step: Mapping[str, StepMetrics] | None
    end_effector: Mapping[str, AxisError]
    wall_time: float
    trajectory: Trajectory


@dataclass(frozen=True)
class StepStudyPoint:
    """FPDESO step response under one variation of the discretisation.

    Attributes:
        label: The variation (control period, TD filter factor, sub-steps).
        step: Step metrics per joint.
    """

    label: str
    step: Mapping[str, StepMetrics]


@dataclass(frozen=True, eq=False)
class ReproductionResult:
    """Everything ``smm-reproduce`` computed.

    Attributes:
        runs: Results by (scenario, controller), in run order.
        scenarios: Scenarios run, in order.
        controllers: Controllers run, in order.
        seed: Noise seed.
        control_period: Control period (s).
        td_config: TD parameters used by every chain.
        checks: Acceptance checks (those whose runs are present).
        step_study: FPDESO step metrics versus control period (empty if not computed).
    """

    runs: Mapping[tuple[str, str], RunResult]
    scenarios: tuple[Scenario, ...]
    controllers: tuple[str, ...]
    seed: int
    control_period: float
    td_config: TrackingDifferentiatorConfig
    checks: tuple[AcceptanceCheck, ...] = ()
    step_study: tuple[StepStudyPoint, ...] = field(default_factory=tuple)

    def run(self, scenario: str, controller: str) -> RunResult | None:
        """The result of one run, or None if it was not run."""
        return self.runs.get((scenario, controller))
