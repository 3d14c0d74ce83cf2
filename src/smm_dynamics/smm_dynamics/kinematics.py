"""Kinematics of the SMM: the rotor's spin angle and the end-effector position (eq. 1, Section V.B)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from smm_dynamics._arrays import FloatArray, is_batch, joint_array, pack_vector, trig_of
from smm_dynamics._generated import spin_angle_gradient_entries
from smm_dynamics.parameters import SMMParameters

__all__ = [
    "end_effector_position",
    "spin_angle",
    "spin_angle_gradient",
]


def spin_angle(q: ArrayLike) -> FloatArray:
    """Spin angle of the rotor, theta = atan2(tan(alpha), cos(beta)).

    Args:
        q: Joint positions (alpha, beta) (rad), shape (..., 2).

    Returns:
        theta (rad), shape q.shape[:-1] (a 0-d array for a single sample).
    """
    q = joint_array(q, "q")
    return np.asarray(np.arctan2(np.tan(q[..., 0]), np.cos(q[..., 1])), dtype=np.float64)


def spin_angle_gradient(q: ArrayLike) -> FloatArray:
    """Gradient of the spin angle, (dtheta/dalpha, dtheta/dbeta).

    Args:
        q: Joint positions (rad), shape (..., 2).

    Returns:
        Gradient (rad/rad), shape (..., 2).
    """
    q = joint_array(q, "q")
    batch = is_batch(q)
    dtheta_dalpha, dtheta_dbeta = spin_angle_gradient_entries(*trig_of(q, batch))
    return pack_vector(dtheta_dalpha, dtheta_dbeta, batch)


def end_effector_position(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """End-effector position p = L (sin b sin theta, -sin b cos theta, cos b) (Section V.B).

    It is L times the third column of the rotation matrix of eq. 1.

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters (link_length L).

    Returns:
        p (m), shape (..., 3).
    """
    q = joint_array(q, "q")
    theta = spin_angle(q)
    sb = np.sin(q[..., 1])
    length = params.link_length
    return np.stack(
        (length * sb * np.sin(theta), -length * sb * np.cos(theta), length * np.cos(q[..., 1])), axis=-1
    )
