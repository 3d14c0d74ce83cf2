"""The offline closed loop of ``smm_analysis.closed_loop`` for N runs at once, and each run's indices.

:func:`run_batch` steps N :class:`RunSettings` (one law, equal durations and periods); :func:`run_scalar`
runs one with the scalar loop. A diverged run (non-finite torque or state) gets NaN indices; the others
carry on.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from smm_controller.chain import make_law
from smm_controller.laws import get_law, law_names, law_table
from smm_controller.limits import OutputLimitConfig
from smm_sim.plant import PlantConfig

from smm_analysis.batch.chain import BatchChain, BatchFLESO, BatchLimiter, BatchModel, BatchTD, make_batch_law
from smm_analysis.batch.plant import BatchPlant
from smm_analysis.closed_loop import DEFAULT_CONTROL_PERIOD, Trajectory, run_closed_loop
from smm_analysis.errors import AnalysisError, ClosedLoopDivergedError
from smm_analysis.metrics import METRICS, Group, joint_indices, step_metrics
from smm_analysis.scenarios import Scenario
from smm_controller import (
    FLESOConfig,
    FPDESOConfig,
    JointController,
    TrackingDifferentiatorConfig,
)
from smm_dynamics import SMMParameters

__all__ = [
    "INDEX_NAMES",
    "SIGN_TOLERANCE",
    "SMOOTH_TOLERANCE",
    "RunSettings",
    "agreement_tolerance",
    "indices_of",
    "run_batch",
    "run_scalar",
    "scalar_indices",
]

FloatArray = NDArray[np.float64]
_NS_PER_S = 1_000_000_000
_JOINTS = ("alpha", "beta")
_BATCHED = tuple(row for row in METRICS if row.batched)
INDEX_NAMES: tuple[str, ...] = tuple(f"{row.column}_{joint}" for row in _BATCHED for joint in _JOINTS)
"""Index columns of a run: ``{column}_{joint}`` of the table's batched metrics; step ones NaN for a sine."""


@dataclass(frozen=True)
class RunSettings:
    """Everything one closed-loop run takes (the arguments of ``run_closed_loop``).

    Attributes:
        scenario: Reference and duration (the plant is ``plant``, not the scenario's).
        controller: A law of ``smm_controller.law_table()`` with a batched twin.
        law: The law's gains (the config type of ``controller``).
        plant: The simulated plant (noise, seed, disturbance, model error, limits, lag).
        td: TD parameters.
        fleso: FLESO parameters (laws that use the disturbance estimate).
        model: The controller's nominal model.
        output: Output limits after the law.
        control_period: Control period (s).
    """

    scenario: Scenario
    controller: str
    law: Any
    plant: PlantConfig
    td: TrackingDifferentiatorConfig = field(default_factory=TrackingDifferentiatorConfig)
    fleso: FLESOConfig = field(default_factory=FLESOConfig)
    model: SMMParameters = field(default_factory=SMMParameters)
    output: OutputLimitConfig = field(default_factory=OutputLimitConfig)
    control_period: float = DEFAULT_CONTROL_PERIOD

    def __post_init__(self) -> None:
        row = law_table().get(self.controller)
        if row is None:
            raise AnalysisError(f"unknown controller {self.controller!r}; known: {', '.join(law_names())}")
        expected = row.config
        if not isinstance(self.law, expected):
            raise AnalysisError(
                f"{self.controller} needs a {expected.__name__}, got {type(self.law).__name__}"
            )

    def make_law(self) -> JointController:
        """The scalar law of these settings."""
        return make_law(self.law, self.model)


def indices_of(
    t_ns: NDArray[np.int64],
    scenario: Scenario,
    position: FloatArray,
    torque: FloatArray,
    desired: FloatArray | None = None,
) -> dict[str, float]:
    """The run's indices (``INDEX_NAMES``) from its true position and command torque, (N + 1, 2) each.

    ``desired`` is the scenario's q_d at the stamps, (N + 1, 2), if already sampled.
    """
    if desired is None:
        desired = scenario.reference().sample(t_ns.astype(np.float64) / _NS_PER_S)[:, 0, :]
    joints = joint_indices(t_ns, desired, position, torque)
    steps = [
        step_metrics(t_ns, position[:, index], scenario.amplitude[index]) if scenario.is_step else None
        for index in range(len(_JOINTS))
    ]
    result: dict[str, float] = {}
    for row in _BATCHED:
        for index, joint in enumerate(_JOINTS):
            if row.group is Group.JOINT:
                value = float(getattr(joints[joint], row.name))
            else:
                step = steps[index]
                value = math.nan if step is None else float(getattr(step, row.name))
            result[f"{row.column}_{joint}"] = value
    return result


def _diverged() -> dict[str, float]:
    return dict.fromkeys(INDEX_NAMES, math.nan)


def run_scalar(settings: RunSettings) -> Trajectory:
    """The run with the scalar loop (``run_closed_loop``), without recorded internals.

    Raises:
        ClosedLoopDivergedError: The loop went unstable.
    """
    return run_closed_loop(
        settings.scenario,
        settings.controller,
        seed=settings.plant.seed,
        control_period=settings.control_period,
        td_config=settings.td,
        fleso_config=settings.fleso,
        controller=settings.make_law(),
        model_params=settings.model,
        plant_config=settings.plant,
        output_limits=settings.output,
        record_internals=False,
    )


def scalar_indices(settings: RunSettings) -> dict[str, float]:
    """:func:`indices_of` of :func:`run_scalar`; NaN for every index if the loop diverged."""
    try:
        trajectory = run_scalar(settings)
    except ClosedLoopDivergedError:
        return _diverged()
    if not np.all(np.isfinite(trajectory.position)):
        return _diverged()  # the plant's state overflowed under a finite torque
    return indices_of(trajectory.t_ns, settings.scenario, trajectory.position, trajectory.command_torque)


def _steps(runs: Sequence[RunSettings]) -> tuple[int, int]:
    periods = {round(run.control_period * _NS_PER_S) for run in runs}
    durations = {round(run.scenario.duration * _NS_PER_S) for run in runs}
    controllers = {run.controller for run in runs}
    if len(periods) != 1 or len(durations) != 1 or len(controllers) != 1:
        raise AnalysisError(
            "every run of a batch needs the same control period, duration and controller, got "
            f"{sorted(periods)} ns, {sorted(durations)} ns, {sorted(controllers)}"
        )
    period_ns, duration_ns = periods.pop(), durations.pop()
    if period_ns <= 0 or duration_ns % period_ns != 0:
        raise AnalysisError(
            f"duration {duration_ns} ns is not a whole number of control periods {period_ns} ns"
        )
    return period_ns, duration_ns // period_ns


def run_batch(runs: Sequence[RunSettings]) -> list[dict[str, float]]:
    """Runs every settings in one batch; returns each run's indices (NaN where it diverged).

    Raises:
        AnalysisError: The runs differ in control period, duration or controller.
    """
    if not runs:
        return []
    position, torque, t_ns, tables, which = _simulate(runs)
    return [
        indices_of(t_ns, run.scenario, position[:, row], torque[:, row], tables[:, which[row], 0])
        if np.all(np.isfinite(torque[:, row]))
        else _diverged()
        for row, run in enumerate(runs)
    ]


def _simulate(
    runs: Sequence[RunSettings],
) -> tuple[FloatArray, FloatArray, NDArray[np.int64], FloatArray, NDArray[np.int64]]:
    """True positions and commands of every run, (N + 1, runs, 2) each (NaN from a divergence on).

    Also the stamps, the references of the distinct scenarios (N + 1, scenarios, 3, 2) and each run's
    scenario index.
    """
    period_ns, steps = _steps(runs)
    samples = steps + 1
    dt = period_ns / _NS_PER_S
    t_ns = np.arange(samples, dtype=np.int64) * period_ns
    times = t_ns.astype(np.float64) / _NS_PER_S
    scenarios = list(dict.fromkeys(run.scenario for run in runs))
    tables = np.stack([scenario.reference().sample(times) for scenario in scenarios], axis=1)
    which = np.array([scenarios.index(run.scenario) for run in runs])
    model = BatchModel([run.model for run in runs])
    controller = runs[0].controller
    law = make_batch_law(controller, [run.law for run in runs], model)
    uses_estimate = get_law(controller).uses_disturbance_estimate
    fleso = BatchFLESO([run.fleso for run in runs], model) if uses_estimate else None
    chain = BatchChain(
        BatchTD([run.td for run in runs]), fleso, law, BatchLimiter([run.output for run in runs])
    )
    plant = BatchPlant([run.plant for run in runs], samples + 1)
    position = np.empty((samples, len(runs), 2))
    command = np.empty((samples, len(runs), 2))
    alive = np.ones(len(runs), dtype=bool)
    with np.errstate(all="ignore"):
        for k in range(samples):
            reference = tables[k, which]
            tau = chain.step(
                plant.measured, plant.applied, (reference[:, 0], reference[:, 1], reference[:, 2]), dt
            )
            alive &= np.all(np.isfinite(tau), axis=1) & np.all(np.isfinite(plant.state), axis=1)
            tau = np.where(alive[:, None], tau, 0.0)
            position[k] = plant.state[:, :2]
            command[k] = np.where(alive[:, None], tau, np.nan)
            plant.step(tau, period_ns)
    return position, command, t_ns, tables, which


SMOOTH_TOLERANCE = 1e-9
"""Relative agreement of a batched run's indices with the scalar loop's (no pure sign in the law)."""
SIGN_TOLERANCE = 1e-3
"""Relative agreement with FPDESO's pure sign (boundary_layer 0, robust_gain > 0): a last-bit difference
(numpy's vectorised sin, cos, exp against ``math``'s) can flip sign(M^-1 e') where it is 0 to rounding;
that moves one step's torque by 2 b_d (< 0.2 N m at the paper's b_d), which the loop absorbs within
a few steps (docs/SWEEPS.md)."""


def agreement_tolerance(settings: RunSettings) -> float:
    """The relative tolerance within which the batched and the scalar loop agree for these settings."""
    law = settings.law
    if isinstance(law, FPDESOConfig) and any(
        phi == 0.0 and b_d > 0.0 for phi, b_d in zip(law.boundary_layer, law.robust_gain, strict=True)
    ):
        return SIGN_TOLERANCE
    return SMOOTH_TOLERANCE
