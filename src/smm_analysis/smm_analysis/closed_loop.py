"""Offline closed loop: the simulated plant and the control chain, in the order of docs/DESIGN.md.

At t_k = k * period (k = 0 .. N, N = duration / period): ``y_k, tau_applied_{k-1} = plant.measure()``
(applied torque zero at k = 0), ``tau_k = chain.step(y_k, tau_applied_{k-1}, r(t_k), dt)``, then
``plant.step(tau_k, dt)`` over [t_k, t_{k+1}]. Deterministic for a seed; a lockstep run of the ROS graph
reproduces it (docs/DESIGN.md, "The control chain and its order").
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from smm_controller.limits import OutputLimitConfig
from smm_sim.plant import PlantConfig, SimulatedPlant, disturbance_torque

from smm_analysis.errors import AnalysisError, ClosedLoopDivergedError, UnknownControllerError
from smm_analysis.scenarios import Scenario, get_scenario
from smm_controller import (
    FLESOConfig,
    JointController,
    TrackingDifferentiatorConfig,
    UnknownLawError,
    build_chain,
)
from smm_dynamics import SMMParameters

__all__ = [
    "DEFAULT_CONTROL_PERIOD",
    "DEFAULT_SUBSTEPS",
    "Trajectory",
    "run_closed_loop",
    "scenario_plant_config",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

DEFAULT_CONTROL_PERIOD = 1e-3
"""Control period of the paper's controllers (s)."""

DEFAULT_SUBSTEPS = 1
"""RK4 sub-steps per control period. One is enough: the torque is held over each period, so RK4 only
integrates the plant's own smooth dynamics over 1 ms; the case2 RMS of every controller changes by less
than 1e-6 relative between 1 and 8 sub-steps (a test pins the agreement on a shortened case2)."""

_NS_PER_S = 1_000_000_000


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One closed-loop run, sampled at every control step (N + 1 samples, t_0 = 0 .. t_N = t_f).

    Attributes:
        scenario: Scenario name.
        controller: Controller name.
        seed: Seed of the plant's noise generator.
        control_period: Control period dt (s).
        model_params: Nominal parameters the controller's model (FLESO, FPDESO) uses.
        plant_params: True plant parameters (inertias scaled by the scenario's model error).
        t_ns: Sample stamps (ns), int64, shape (N + 1,).
        reference: q_d, q_d', q_d'' at the stamps, shape (N + 1, 3, 2) (rad, rad/s, rad/s^2).
        measured_position: Encoder position y_k given to the chain (rad), shape (N + 1, 2).
        position: True joint position q (rad), shape (N + 1, 2).
        velocity: True joint velocity q' (rad/s), shape (N + 1, 2).
        command_torque: Chain output tau_k (N m), shape (N + 1, 2).
        applied_torque: Mean torque the plant applied over [t_k, t_{k+1}] (N m), shape (N + 1, 2).
        disturbance_estimate: FLESO estimate xi~_k (N m; zeros without FLESO or when internals are
            not recorded), shape (N + 1, 2).
        disturbance_torque: True external disturbance at t_k (N m), shape (N + 1, 2).
        internals: Every chain internal (``td.x1``, ``fleso.bandwidth``, ``controller.kp``, ...)
            at every step, each shape (N + 1, 2); empty if not recorded.
    """

    scenario: str
    controller: str
    seed: int
    control_period: float
    model_params: SMMParameters
    plant_params: SMMParameters
    t_ns: IntArray
    reference: FloatArray
    measured_position: FloatArray
    position: FloatArray
    velocity: FloatArray
    command_torque: FloatArray
    applied_torque: FloatArray
    disturbance_estimate: FloatArray
    disturbance_torque: FloatArray
    internals: Mapping[str, FloatArray] = field(default_factory=dict)

    @property
    def time(self) -> FloatArray:
        """Sample times (s), shape (N + 1,)."""
        return self.t_ns.astype(np.float64) / _NS_PER_S

    @property
    def desired_position(self) -> FloatArray:
        """q_d at the stamps (rad), shape (N + 1, 2)."""
        return self.reference[:, 0, :]

    @property
    def tracking_error(self) -> FloatArray:
        """E = q_d - q with the true position (rad), shape (N + 1, 2)."""
        return self.reference[:, 0, :] - self.position


def scenario_plant_config(
    scenario: Scenario,
    *,
    seed: int = 0,
    control_period: float = DEFAULT_CONTROL_PERIOD,
    substeps: int = DEFAULT_SUBSTEPS,
    params: SMMParameters | None = None,
) -> PlantConfig:
    """The plant of a scenario: its noise, disturbance and model error; actuator limits and lag off.

    Args:
        scenario: The scenario.
        seed: Noise seed.
        control_period: Control period (s).
        substeps: RK4 sub-steps per control period.
        params: Nominal parameters (default ``SMMParameters()``); the plant scales their inertias.

    Returns:
        The plant configuration.
    """
    return PlantConfig(
        params=params if params is not None else SMMParameters(),
        inertia_scale=scenario.inertia_scale,
        noise_std=scenario.noise_std,
        seed=seed,
        disturbance=scenario.disturbance,
        substeps=substeps,
        control_period=control_period,
    )


def run_closed_loop(
    scenario: Scenario | str,
    controller_name: str,
    *,
    seed: int = 0,
    control_period: float = DEFAULT_CONTROL_PERIOD,
    td_config: TrackingDifferentiatorConfig | None = None,
    fleso_config: FLESOConfig | None = None,
    controller: JointController | None = None,
    model_params: SMMParameters | None = None,
    plant_config: PlantConfig | None = None,
    substeps: int = DEFAULT_SUBSTEPS,
    record_internals: bool = True,
    output_limits: OutputLimitConfig | None = None,
) -> Trajectory:
    """Runs one scenario with one controller in closed loop.

    Args:
        scenario: A :class:`Scenario` or the name of one in ``SCENARIOS``.
        controller_name: A law of ``smm_controller.law_table()``.
        seed: Seed of the plant's noise generator.
        control_period: Control period dt (s); the scenario's duration must be a whole number of
            periods (to 1 ns).
        td_config: TD parameters (default: ``smm_controller``'s defaults).
        fleso_config: FLESO parameters (laws that use the disturbance estimate; default: the paper's).
        controller: Controller instance replacing the default-gain one (retuned sets).
        model_params: Nominal model of the controller (default ``SMMParameters()``).
        plant_config: Full plant configuration, replacing the one derived from the scenario
            (its ``control_period`` is ignored: the loop uses ``control_period``).
        substeps: RK4 sub-steps per period when the plant is derived from the scenario.
        record_internals: Record every chain internal at every step (costs about a third of the
            run time; off for benchmarks of the loop itself).
        output_limits: Torque and rate limits after the law (default: ``OutputLimitConfig()``).

    Returns:
        The sampled run.

    Raises:
        UnknownScenarioError: Unknown scenario name.
        UnknownControllerError: Unknown controller name.
        AnalysisError: The duration is not a whole number of control periods.
        ClosedLoopDivergedError: The chain produced a non-finite torque (unstable loop).
    """
    spec = get_scenario(scenario) if isinstance(scenario, str) else scenario
    nominal = model_params if model_params is not None else SMMParameters()
    if not (math.isfinite(control_period) and control_period > 0.0):
        raise AnalysisError(f"control_period must be a finite number > 0 s, got {control_period!r}")
    period_ns = round(control_period * _NS_PER_S)
    duration_ns = round(spec.duration * _NS_PER_S)
    if period_ns <= 0 or duration_ns % period_ns != 0:
        raise AnalysisError(
            f"duration {spec.duration!r} s is not a whole number of control periods {control_period!r} s"
        )
    steps = duration_ns // period_ns
    config = (
        plant_config
        if plant_config is not None
        else scenario_plant_config(
            spec, seed=seed, control_period=control_period, substeps=substeps, params=nominal
        )
    )
    plant = SimulatedPlant(config)
    try:
        chain = build_chain(
            controller_name, nominal, law=controller, td=td_config, fleso=fleso_config, limiter=output_limits
        )
    except UnknownLawError as error:
        raise UnknownControllerError(str(error)) from None
    dt = period_ns / _NS_PER_S

    t_ns = np.arange(steps + 1, dtype=np.int64) * period_ns
    reference = spec.reference().sample(t_ns.astype(np.float64) / _NS_PER_S)
    reference_rows = reference.tolist()
    samples = steps + 1
    # Per step one tuple of floats (measured y, true q, q', command, disturbance), stacked at the end:
    # cheaper than writing numpy rows every step.
    rows: list[tuple[float, ...]] = []
    applied_rows: list[tuple[float, float]] = []
    snapshots: list[Mapping[str, FloatArray]] = []
    disturbance_model = config.disturbance
    measure_floats = plant.measure_floats
    chain_step = chain.step_floats
    plant_step = plant.step
    isfinite = math.isfinite

    for k in range(samples):
        # y_k and the torque applied over [t_{k-1}, t_k]: plant.measure() as floats.
        y0, y1, effort0, effort1 = measure_floats()
        # step_floats is chain.step without the per-call array validation (the plant's outputs are
        # finite by construction); a test pins that both give the same torques bit for bit.
        tau = chain_step((y0, y1), (effort0, effort1), reference_rows[k], dt)
        tau0, tau1 = tau
        if not (isfinite(tau0) and isfinite(tau1)):
            raise ClosedLoopDivergedError(
                f"{controller_name} on {spec.name}: non-finite torque {tau!r} at step {k} "
                f"(t = {k * dt:.3f} s); the closed loop went unstable"
            )
        # The true state and disturbance at t_k, as plant.ground_truth reports them.
        dist0, dist1 = disturbance_torque(disturbance_model, plant.time_ns / _NS_PER_S)
        alpha, beta, alpha_dot, beta_dot = plant.state_floats
        rows.append((y0, y1, alpha, beta, alpha_dot, beta_dot, tau0, tau1, dist0, dist1))
        if record_internals:
            snapshots.append(chain.internals)
        if k > 0:
            applied_rows.append((effort0, effort1))  # the torque that acted over [t_{k-1}, t_k]
        plant_step(tau, dt)
    applied_rows.append(measure_floats()[2:])

    # fromiter over the flattened rows: the same values as np.array(rows), without its shape discovery.
    table = np.fromiter(itertools.chain.from_iterable(rows), dtype=np.float64, count=10 * samples).reshape(
        samples, 10
    )
    measured, position, velocity, command, disturbance = (
        np.ascontiguousarray(table[:, column : column + 2]) for column in range(0, 10, 2)
    )
    applied = np.array(applied_rows).reshape(samples, 2)
    recorded: dict[str, FloatArray] = {}
    if snapshots:
        recorded = {key: np.array([snapshot[key] for snapshot in snapshots]) for key in snapshots[0]}
    estimate = recorded["disturbance_estimate"].copy() if record_internals else np.zeros((samples, 2))

    return Trajectory(
        scenario=spec.name,
        controller=controller_name,
        seed=seed,
        control_period=dt,
        model_params=nominal,
        plant_params=config.true_params,
        t_ns=t_ns,
        reference=reference,
        measured_position=measured,
        position=position,
        velocity=velocity,
        command_torque=command,
        applied_torque=applied,
        disturbance_estimate=estimate,
        disturbance_torque=disturbance,
        internals=recorded,
    )
