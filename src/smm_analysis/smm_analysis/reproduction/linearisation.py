"""The baselines' equivalent linear loops at q = 0 (stiffness, natural frequency, damping ratio)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from smm_controller import FPDConfig, NPDConfig, PIDConfig
from smm_dynamics import SMMParameters, mass_matrix

__all__ = ["BaselineLinearisation", "baseline_linearisations"]

_JOINTS = ("alpha", "beta")


@dataclass(frozen=True)
class BaselineLinearisation:
    """A torque-output baseline linearised at q = 0 for small errors, on the nominal plant.

    Attributes:
        controller: Controller name.
        joint: ``alpha`` or ``beta``.
        kp: Small-error proportional gain (N m/rad).
        kd: Small-error derivative gain (N m s/rad).
        inertia: Diagonal of M(0) for the joint (kg m^2).
        stiffness: kp minus the destabilising gravity stiffness m_c g l_c on beta (N m/rad).
        natural_frequency: sqrt(stiffness / inertia) (rad/s).
        damping_ratio: (kd + f_v) / (2 sqrt(stiffness inertia)), friction included.
    """

    controller: str
    joint: str
    kp: float
    kd: float
    inertia: float
    stiffness: float
    natural_frequency: float
    damping_ratio: float


def baseline_linearisations(params: SMMParameters) -> list[BaselineLinearisation]:
    """Equivalent linear loops of the baselines with the paper's gains at q = 0.

    PID: P and D only; NPD: its gains below the thresholds; FPD: k_p0, k_d0. At q = 0, M = diag(I55, I22).

    Args:
        params: Plant parameters.

    Returns:
        One entry per baseline and joint.
    """
    pid, npd, fpd = PIDConfig(), NPDConfig(), FPDConfig()
    gains = {
        "pid": (pid.kp, pid.kd),
        "npd": (
            tuple(k * d ** (r - 1.0) for k, d, r in zip(npd.k_np, npd.delta_p, npd.rho_p, strict=True)),
            tuple(k * d ** (r - 1.0) for k, d, r in zip(npd.k_nd, npd.delta_d, npd.rho_d, strict=True)),
        ),
        "fpd": (fpd.fuzzy.kp0, fpd.fuzzy.kd0),
    }
    inertia = mass_matrix((0.0, 0.0), params)
    gravity_stiffness = (0.0, params.gravity_sign * params.mass_lever * params.gravity)
    result = []
    for name, (kp, kd) in gains.items():
        for index, joint in enumerate(_JOINTS):
            stiffness = kp[index] - gravity_stiffness[index]
            mass = float(inertia[index, index])
            damping = kd[index] + params.viscous_friction[index]
            result.append(
                BaselineLinearisation(
                    controller=name,
                    joint=joint,
                    kp=kp[index],
                    kd=kd[index],
                    inertia=mass,
                    stiffness=stiffness,
                    natural_frequency=math.sqrt(stiffness / mass) if stiffness > 0 else math.nan,
                    damping_ratio=damping / (2.0 * math.sqrt(stiffness * mass))
                    if stiffness > 0
                    else math.nan,
                )
            )
    return result
