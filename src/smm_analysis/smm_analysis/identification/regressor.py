"""The SMM's inverse dynamics as a regressor linear in its parameters: tau = Y(q, q', q'') theta.

theta = (I11, I22, I44, I55, m_c l_c, f_v, f_c, tau_0) with the last three per joint (alpha, beta):
M is linear in the four inertias, C q' in I11 and I55, G in the gravity lever (g and the gravity sign
known), F in the viscous and Coulomb levels and the offset (docs/IDENTIFICATION.md).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from smm_dynamics import SMMParameters, inverse_dynamics

__all__ = ["PARAMETER_NAMES", "PARAMETER_UNITS", "parameter_vector", "parameters_from_vector", "regressor"]

FloatArray = NDArray[np.float64]

#: Names of theta's entries, in order.
PARAMETER_NAMES: tuple[str, ...] = (
    "I11",
    "I22",
    "I44",
    "I55",
    "mass_lever",
    "viscous_friction.alpha",
    "viscous_friction.beta",
    "coulomb_friction.alpha",
    "coulomb_friction.beta",
    "torque_offset.alpha",
    "torque_offset.beta",
)
#: Units of theta's entries.
PARAMETER_UNITS: tuple[str, ...] = (
    *("kg m^2",) * 4,
    "kg m",
    *("N m s/rad",) * 2,
    *("N m",) * 4,
)
_INERTIAS = ("I11", "I22", "I44", "I55")
# M and C q' are linear in the inertias: a column is the rigid-body torque with one inertia one larger
# than at the unit point, less the torque at the unit point (no gravity, no friction).
_UNIT = SMMParameters(I11=1.0, I22=1.0, I44=1.0, I55=1.0, mass_lever=0.0, viscous_friction=(0.0, 0.0))


def regressor(
    q: ArrayLike, qd: ArrayLike, qdd: ArrayLike, *, gravity: float, gravity_sign: float
) -> FloatArray:
    """Y such that inverse_dynamics(q, q', q'', params) = Y @ parameter_vector(params).

    Args:
        q: Joint positions (rad), shape (N, 2).
        qd: Joint velocities (rad/s), shape (N, 2).
        qdd: Joint accelerations (rad/s^2), shape (N, 2).
        gravity: g (m/s^2).
        gravity_sign: +1.0 or -1.0 as in SMMParameters.

    Returns:
        Y, shape (N, 2, 11): rows (alpha, beta) torque per unit of each parameter.
    """
    q, qd, qdd = (np.asarray(value, dtype=np.float64) for value in (q, qd, qdd))
    if not (q.ndim == 2 and q.shape[1] == 2 and q.shape == qd.shape == qdd.shape):
        raise ValueError(
            f"q, qd, qdd must have the same shape (N, 2), got {q.shape}, {qd.shape}, {qdd.shape}"
        )
    columns = np.zeros((q.shape[0], 2, len(PARAMETER_NAMES)))
    unit_torque = inverse_dynamics(q, qd, qdd, _UNIT, friction=False)
    for index, name in enumerate(_INERTIAS):
        raised = dataclasses.replace(_UNIT, **{name: 2.0})  # type: ignore[arg-type]
        columns[:, :, index] = inverse_dynamics(q, qd, qdd, raised, friction=False) - unit_torque
    columns[:, 1, 4] = -gravity_sign * gravity * np.sin(q[:, 1])
    for joint in (0, 1):
        columns[:, joint, 5 + joint] = qd[:, joint]
        columns[:, joint, 7 + joint] = np.sign(qd[:, joint])
        columns[:, joint, 9 + joint] = 1.0
    return columns


def parameter_vector(params: SMMParameters) -> FloatArray:
    """The vector theta of ``params`` in the order of :data:`PARAMETER_NAMES`, shape (11,)."""
    return np.array(
        [
            params.I11,
            params.I22,
            params.I44,
            params.I55,
            params.mass_lever,
            *params.viscous_friction,
            *params.coulomb_friction,
            *params.torque_offset,
        ],
        dtype=np.float64,
    )


def parameters_from_vector(theta: ArrayLike, base: SMMParameters) -> SMMParameters:
    """``base`` with the fields of theta (:data:`PARAMETER_NAMES` order) replaced; gravity, sign, L kept.

    Raises:
        ValueError: theta is not 11 values, or SMMParameters rejects one of them.
    """
    values = np.asarray(theta, dtype=np.float64)
    if values.shape != (len(PARAMETER_NAMES),):
        raise ValueError(f"theta must have shape ({len(PARAMETER_NAMES)},), got {values.shape}")
    v = [float(value) for value in values]
    return dataclasses.replace(
        base,
        I11=v[0],
        I22=v[1],
        I44=v[2],
        I55=v[3],
        mass_lever=v[4],
        viscous_friction=(v[5], v[6]),
        coulomb_friction=(v[7], v[8]),
        torque_offset=(v[9], v[10]),
    )
