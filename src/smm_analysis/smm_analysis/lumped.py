"""The lumped disturbance the FLESO estimates, from a simulator run's ground truth, in its two parts.

xi = model error + tau_dist; the formula: docs/IDENTIFICATION.md, "The lumped disturbance".
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from smm_sim.plant import disturbance_torque

from smm_analysis.closed_loop import Trajectory
from smm_dynamics import SMMParameters, forward_dynamics, inverse_dynamics

__all__ = [
    "LumpedDisturbance",
    "lumped_disturbance",
    "recorded_lumped_disturbance",
    "trajectory_lumped_disturbance",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LumpedDisturbance:
    """The true lumped disturbance and its parts, each (N m), shape (N, 2).

    Attributes:
        total: What the observer estimates: model error + external.
        model_error: The plant's torque the model does not have.
        external: The external disturbance tau_dist.
    """

    total: FloatArray
    model_error: FloatArray
    external: FloatArray


def lumped_disturbance(
    position: FloatArray,
    velocity: FloatArray,
    applied: FloatArray,
    external: FloatArray,
    *,
    plant: SMMParameters,
    model: SMMParameters,
    compensate_friction: bool = False,
) -> LumpedDisturbance:
    """The lumped disturbance at the true states, with the torque ``applied`` acting just after them.

    Args:
        position: True q (rad), shape (N, 2).
        velocity: True q' (rad/s), shape (N, 2).
        applied: Torque acting from each sample on (N m), shape (N, 2).
        external: tau_dist at the samples (N m), shape (N, 2).
        plant: The plant's true parameters.
        model: The observer's nominal model.
        compensate_friction: Whether the observer's model holds the model's friction.
    """
    acceleration = forward_dynamics(position, velocity, applied, plant, tau_dist=external)
    model_error = inverse_dynamics(position, velocity, acceleration, plant) - inverse_dynamics(
        position, velocity, acceleration, model, friction=compensate_friction
    )
    return LumpedDisturbance(
        total=model_error + external, model_error=model_error, external=np.asarray(external)
    )


def trajectory_lumped_disturbance(run: Trajectory, *, compensate_friction: bool = False) -> LumpedDisturbance:
    """:func:`lumped_disturbance` of an offline closed-loop run (its applied torque acts after each stamp)."""
    return lumped_disturbance(
        run.position,
        run.velocity,
        run.applied_torque,
        run.disturbance_torque,
        plant=run.plant_params,
        model=run.model_params,
        compensate_friction=compensate_friction,
    )


def _parameters(values: Mapping[str, Any], prefix: str) -> SMMParameters:
    fields = {field.name for field in dataclasses.fields(SMMParameters)}
    chosen: dict[str, Any] = {
        key[len(prefix) :]: tuple(value) if isinstance(value, list) else value
        for key, value in values.items()
        if key.startswith(prefix) and key[len(prefix) :] in fields
    }
    return SMMParameters(**chosen)


def recorded_lumped_disturbance(
    parameters: Mapping[str, Mapping[str, Any]],
    time: FloatArray,
    position: FloatArray,
    applied_before: FloatArray,
) -> LumpedDisturbance | None:
    """The lumped disturbance of a recorded simulator run, or None when the bag does not say enough.

    Args:
        parameters: The manifest's ``{node: {parameter: value}}``: the simulator's ``params.*``,
            ``inertia_scale`` and ``disturbance``, the observer's ``model.*`` and
            ``fleso.compensate_friction``.
        time: Seconds since the first step, shape (N,).
        position: Ground-truth q (rad), shape (N, 2).
        applied_before: joint_states effort, the torque over the interval before each stamp (N m),
            shape (N, 2).
    """
    sim = next((values for node, values in parameters.items() if node.endswith("smm_sim_node")), None)
    observer = next(
        (values for node, values in parameters.items() if node.endswith("fleso_node")),
        next((values for node, values in parameters.items() if node.endswith("controller_node")), None),
    )
    if sim is None or observer is None or position.shape[0] < 3:
        return None
    try:
        plant = _parameters(sim, "params.").with_inertia_scale(float(sim.get("inertia_scale", 1.0)))
        model = _parameters(observer, "model.")
        external = np.array([disturbance_torque(str(sim.get("disturbance", "none")), float(t)) for t in time])
    except (TypeError, ValueError):
        return None
    velocity = np.gradient(position, time, axis=0)
    # The effort at stamp k + 1 is the torque that acted after stamp k.
    applied = np.vstack([applied_before[1:], applied_before[-1:]])
    return lumped_disturbance(
        position,
        velocity,
        applied,
        external,
        plant=plant,
        model=model,
        compensate_friction=bool(observer.get("fleso.compensate_friction", False)),
    )
