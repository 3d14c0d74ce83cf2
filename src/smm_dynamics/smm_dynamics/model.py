"""Rigid-body model of the 2-DOF SMM on arrays (SPEC section 1, paper eq. 1-2 and Appendix A).

    M(q) q'' + C(q, q') q' + G(q) + F(q') + tau_dist = tau,   q = (alpha, beta) (rad), tau (N m).

Functions take one sample (shape (2,)) or a batch (shape (..., 2), broadcast). The kinematics are in
:mod:`smm_dynamics.kinematics`, the RK4 in :mod:`smm_dynamics.integration`, the plain-float fast path in
:mod:`smm_dynamics.fast_path`. Forms and costs: docs/DYNAMICS.md.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from smm_dynamics._arrays import (
    FloatArray,
    components,
    is_batch,
    joint_array,
    pack_matrix,
    pack_vector,
    trig_of,
)
from smm_dynamics._generated import coriolis_matrix_entries, mass_matrix_gradient_entries
from smm_dynamics._terms import (
    acceleration,
    coriolis_components,
    friction_components,
    gravity_beta,
    has_coulomb_or_offset,
    mass_entries,
)
from smm_dynamics.parameters import SMMParameters

__all__ = [
    "coriolis_matrix",
    "coriolis_vector",
    "forward_dynamics",
    "friction_torque",
    "gravity_vector",
    "inverse_dynamics",
    "kinetic_energy",
    "mass_matrix",
    "mass_matrix_gradient",
    "mass_matrix_inverse",
    "mass_matrix_time_derivative",
    "potential_energy",
    "rigid_body_terms",
    "total_energy",
]


def mass_matrix(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Inertia matrix M(q) of Appendix A.

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        M (kg m^2), symmetric, shape (..., 2, 2).
    """
    q = joint_array(q, "q")
    batch = is_batch(q)
    m11, m12, m22 = mass_entries(trig_of(q, batch), params)
    return pack_matrix(m11, m12, m12, m22, batch)


def mass_matrix_inverse(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Inverse of the inertia matrix, in closed form.

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        M^-1 (1/(kg m^2)), shape (..., 2, 2).
    """
    q = joint_array(q, "q")
    batch = is_batch(q)
    m11, m12, m22 = mass_entries(trig_of(q, batch), params)
    inv_det = 1.0 / (m11 * m22 - m12 * m12)
    off_diagonal = -m12 * inv_det
    return pack_matrix(m22 * inv_det, off_diagonal, off_diagonal, m11 * inv_det, batch)


def mass_matrix_gradient(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Exact partial derivatives of M with respect to q.

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        dM/dq (kg m^2/rad), shape (..., 2, 2, 2); element [..., k, i, j] is dM_ij/dq_k.
    """
    q = joint_array(q, "q")
    batch = is_batch(q)
    d11_a, d12_a, d22_a, d11_b, d12_b, d22_b = mass_matrix_gradient_entries(
        *trig_of(q, batch), params.I11, params.I55
    )
    return np.stack(
        (pack_matrix(d11_a, d12_a, d12_a, d22_a, batch), pack_matrix(d11_b, d12_b, d12_b, d22_b, batch)),
        axis=-3,
    )


def mass_matrix_time_derivative(q: ArrayLike, qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """dM/dt = sum_k dM/dq_k qd_k along a trajectory.

    Args:
        q: Joint positions (rad), shape (..., 2).
        qd: Joint velocities (rad/s), shape (..., 2).
        params: Plant parameters.

    Returns:
        dM/dt (kg m^2/s), shape (..., 2, 2).
    """
    gradient = mass_matrix_gradient(q, params)
    qd = joint_array(qd, "qd")
    return np.asarray(np.einsum("...kij,...k->...ij", gradient, qd), dtype=np.float64)


def coriolis_matrix(q: ArrayLike, qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """Christoffel-form Coriolis/centripetal matrix C(q, qd); dM/dt - 2C is skew-symmetric.

    Args:
        q: Joint positions (rad), shape (..., 2).
        qd: Joint velocities (rad/s), shape (..., 2).
        params: Plant parameters.

    Returns:
        C (N m s/rad = kg m^2/s), shape (..., 2, 2).
    """
    q = joint_array(q, "q")
    qd = joint_array(qd, "qd")
    batch = is_batch(q, qd)
    c11, c12, c21, c22 = coriolis_matrix_entries(
        *trig_of(q, batch), *components(qd, batch), params.I11, params.I55
    )
    return pack_matrix(c11, c12, c21, c22, batch)


def coriolis_vector(q: ArrayLike, qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """Coriolis/centripetal torque C(q, qd) qd.

    Args:
        q: Joint positions (rad), shape (..., 2).
        qd: Joint velocities (rad/s), shape (..., 2).
        params: Plant parameters.

    Returns:
        C qd (N m), shape (..., 2).
    """
    q = joint_array(q, "q")
    qd = joint_array(qd, "qd")
    batch = is_batch(q, qd)
    return pack_vector(*coriolis_components(trig_of(q, batch), *components(qd, batch), params), batch)


def rigid_body_terms(
    alpha: float, beta: float, alpha_dot: float, beta_dot: float, params: SMMParameters
) -> tuple[float, float, float, float, float, float, float]:
    """M(q), C(q, q') q' and G(q) for one sample on plain floats, without any numpy array.

    For control laws that do their 2x2 algebra on floats every control step.

    Args:
        alpha: Joint position alpha (rad).
        beta: Joint position beta (rad).
        alpha_dot: Joint velocity alpha' (rad/s).
        beta_dot: Joint velocity beta' (rad/s).
        params: Plant parameters.

    Returns:
        (M11, M12, M22, (C q')_alpha, (C q')_beta, G_alpha, G_beta); M in kg m^2, torques in N m.
    """
    alpha, beta, alpha_dot, beta_dot = float(alpha), float(beta), float(alpha_dot), float(beta_dot)
    trig = (math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta))
    m11, m12, m22 = mass_entries(trig, params)
    coriolis_alpha, coriolis_beta = coriolis_components(trig, alpha_dot, beta_dot, params)
    return m11, m12, m22, coriolis_alpha, coriolis_beta, 0.0, gravity_beta(trig[2], params)


def potential_energy(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Gravity potential V = gravity_sign m_c l_c g cos(beta).

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        V (J), shape q.shape[:-1].
    """
    q = joint_array(q, "q")
    return np.asarray(
        params.gravity_sign * params.mass_lever * params.gravity * np.cos(q[..., 1]), dtype=np.float64
    )


def gravity_vector(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Gravity torque G(q) = dV/dq = (0, -gravity_sign m_c l_c g sin(beta)).

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        G (N m), shape (..., 2).
    """
    q = joint_array(q, "q")
    batch = is_batch(q)
    _, beta = components(q, batch)
    if batch:
        sb = np.sin(beta)
        return pack_vector(np.zeros_like(sb), gravity_beta(sb, params), batch)
    return pack_vector(0.0, gravity_beta(math.sin(beta), params), batch)


def friction_torque(qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """Friction F(qd) = diag(f_v) qd + diag(f_c) sign(qd) + offset, sign(0) = 0.

    Args:
        qd: Joint velocities (rad/s), shape (..., 2).
        params: Plant parameters.

    Returns:
        F (N m), shape (..., 2).
    """
    qd = joint_array(qd, "qd")
    friction = qd * np.asarray(params.viscous_friction)
    if has_coulomb_or_offset(params):
        coulomb = np.asarray(params.coulomb_friction) * np.sign(qd)
        friction = friction + coulomb + np.asarray(params.torque_offset)
    return np.asarray(friction, dtype=np.float64)


def kinetic_energy(q: ArrayLike, qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """Kinetic energy T = 0.5 qd^T M(q) qd.

    Args:
        q: Joint positions (rad), shape (..., 2).
        qd: Joint velocities (rad/s), shape (..., 2).
        params: Plant parameters.

    Returns:
        T (J), shape of the broadcast batch (0-d for a single sample).
    """
    mass = mass_matrix(q, params)
    qd = joint_array(qd, "qd")
    return np.asarray(0.5 * np.einsum("...i,...ij,...j->...", qd, mass, qd), dtype=np.float64)


def total_energy(q: ArrayLike, qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """Total mechanical energy T + V (J), shape of the broadcast batch."""
    return np.asarray(kinetic_energy(q, qd, params) + potential_energy(q, params), dtype=np.float64)


def forward_dynamics(
    q: ArrayLike,
    qd: ArrayLike,
    tau: ArrayLike,
    params: SMMParameters,
    *,
    tau_dist: ArrayLike | None = None,
    friction: bool = True,
) -> FloatArray:
    """Joint accelerations from eq. 2: qdd = M^-1 (tau - C qd - G - F - tau_dist).

    Args:
        q: Joint positions (rad), shape (..., 2).
        qd: Joint velocities (rad/s), shape (..., 2).
        tau: Applied torque (N m), shape (..., 2).
        params: Plant parameters.
        tau_dist: External disturbance torque xi_edis (N m), shape (..., 2); None for zero.
        friction: Whether to include the friction F(qd) (viscous, Coulomb and offset).

    Returns:
        qdd (rad/s^2), shape (..., 2).
    """
    arrays = [joint_array(q, "q"), joint_array(qd, "qd"), joint_array(tau, "tau")]
    if tau_dist is not None:
        arrays.append(joint_array(tau_dist, "tau_dist"))
    batch = is_batch(*arrays)
    alpha, beta = components(arrays[0], batch)
    alpha_dot, beta_dot = components(arrays[1], batch)
    disturbance = components(arrays[3], batch) if tau_dist is not None else None
    accel = acceleration(
        batch=batch,
        alpha=alpha,
        beta=beta,
        alpha_dot=alpha_dot,
        beta_dot=beta_dot,
        tau=components(arrays[2], batch),
        tau_dist=disturbance,
        params=params,
        friction=friction,
    )
    return pack_vector(*accel, batch)


def inverse_dynamics(
    q: ArrayLike,
    qd: ArrayLike,
    qdd: ArrayLike,
    params: SMMParameters,
    *,
    tau_dist: ArrayLike | None = None,
    friction: bool = True,
) -> FloatArray:
    """Torque from eq. 2: tau = M qdd + C qd + G + F + tau_dist.

    Args:
        q: Joint positions (rad), shape (..., 2).
        qd: Joint velocities (rad/s), shape (..., 2).
        qdd: Joint accelerations (rad/s^2), shape (..., 2).
        params: Plant parameters.
        tau_dist: External disturbance torque (N m), shape (..., 2); None for zero.
        friction: Whether to include the friction F(qd) (viscous, Coulomb and offset).

    Returns:
        tau (N m), shape (..., 2).
    """
    q = joint_array(q, "q")
    qd = joint_array(qd, "qd")
    qdd = joint_array(qdd, "qdd")
    dist = joint_array(tau_dist, "tau_dist") if tau_dist is not None else None
    batch = is_batch(q, qd, qdd) or (dist is not None and dist.ndim > 1)
    trig = trig_of(q, batch)
    alpha_dot, beta_dot = components(qd, batch)
    alpha_ddot, beta_ddot = components(qdd, batch)
    m11, m12, m22 = mass_entries(trig, params)
    coriolis_alpha, coriolis_beta = coriolis_components(trig, alpha_dot, beta_dot, params)
    tau_alpha = m11 * alpha_ddot + m12 * beta_ddot + coriolis_alpha
    tau_beta = m12 * alpha_ddot + m22 * beta_ddot + coriolis_beta + gravity_beta(trig[2], params)
    if friction:
        friction_alpha, friction_beta = friction_components(alpha_dot, beta_dot, params)
        tau_alpha = tau_alpha + friction_alpha
        tau_beta = tau_beta + friction_beta
    if dist is not None:
        dist_alpha, dist_beta = components(dist, batch)
        tau_alpha = tau_alpha + dist_alpha
        tau_beta = tau_beta + dist_beta
    return pack_vector(tau_alpha, tau_beta, batch)
