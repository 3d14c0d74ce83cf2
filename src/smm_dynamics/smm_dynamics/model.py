"""Rigid-body model of the 2-DOF SMM (SPEC section 1, paper eq. 1-2 and Appendix A).

    M(q) q'' + C(q, q') q' + G(q) + F(q') + tau_dist = tau,   q = (alpha, beta) (rad), tau (N m).

Array functions take one sample (shape (2,)) or a batch (shape (..., 2), broadcast); the ``*_floats``
functions are the plain-float fast path (spin form, equal up to rounding). Forms and costs: docs/DYNAMICS.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from smm_dynamics._generated import (
    coriolis_matrix_entries,
    forward_dynamics_entries_spin_form,
    mass_matrix_entries,
    mass_matrix_entries_spin_form,
    mass_matrix_gradient_entries,
    rigid_body_entries_spin_form,
    rk4_step_spin_form,
    spin_angle_gradient_entries,
)
from smm_dynamics.parameters import SMMParameters

__all__ = [
    "coriolis_matrix",
    "coriolis_vector",
    "end_effector_position",
    "forward_dynamics",
    "forward_dynamics_floats",
    "friction_floats",
    "friction_torque",
    "gravity_vector",
    "inverse_dynamics",
    "kinetic_energy",
    "mass_matrix",
    "mass_matrix_floats",
    "mass_matrix_gradient",
    "mass_matrix_inverse",
    "mass_matrix_time_derivative",
    "potential_energy",
    "rigid_body_floats",
    "rigid_body_terms",
    "rk4_stages",
    "rk4_step",
    "rk4_step_floats",
    "spin_angle",
    "spin_angle_gradient",
    "total_energy",
]

FloatArray = NDArray[np.float64]
# A Python float (single-sample path) or a numpy array (batch path); only arithmetic is applied to it.
_Real = Any


def _joint_array(value: ArrayLike, name: str) -> FloatArray:
    array = np.asarray(value, dtype=np.float64)
    if array.ndim == 0 or array.shape[-1] != 2:
        raise ValueError(f"{name} must have shape (2,) or (..., 2), got shape {array.shape}")
    return array


def _is_batch(*arrays: FloatArray) -> bool:
    return any(array.ndim > 1 for array in arrays)


def _components(array: FloatArray, batch: bool) -> tuple[_Real, _Real]:
    if batch:
        return array[..., 0], array[..., 1]
    first, second = array.tolist()
    return first, second


def _trig(q: FloatArray, batch: bool) -> tuple[_Real, _Real, _Real, _Real]:
    alpha, beta = _components(q, batch)
    if batch:
        return np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta)
    return math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)


def _pack_vector(first: _Real, second: _Real, batch: bool) -> FloatArray:
    if batch:
        return np.stack(np.broadcast_arrays(first, second), axis=-1)
    return np.array((first, second), dtype=np.float64)


def _pack_matrix(m11: _Real, m12: _Real, m21: _Real, m22: _Real, batch: bool) -> FloatArray:
    if batch:
        entries = np.broadcast_arrays(m11, m12, m21, m22)
        return np.stack(entries, axis=-1).reshape((*entries[0].shape, 2, 2))
    return np.array(((m11, m12), (m21, m22)), dtype=np.float64)


def _mass_entries(trig: tuple[_Real, _Real, _Real, _Real], params: SMMParameters) -> tuple[_Real, ...]:
    return mass_matrix_entries(*trig, params.I11, params.I22, params.I44, params.I55)


def _gravity_coefficient(params: SMMParameters) -> float:
    # V = s m_c l_c g cos(beta) depends on beta only, so G = (0, dV/dbeta) = (0, coefficient sin(beta)).
    return -params.gravity_sign * params.mass_lever * params.gravity


def _gravity_beta(sb: _Real, params: SMMParameters) -> _Real:
    return _gravity_coefficient(params) * sb


def spin_angle(q: ArrayLike) -> FloatArray:
    """Spin angle of the rotor, theta = atan2(tan(alpha), cos(beta)).

    Args:
        q: Joint positions (alpha, beta) (rad), shape (..., 2).

    Returns:
        theta (rad), shape q.shape[:-1] (a 0-d array for a single sample).
    """
    q = _joint_array(q, "q")
    return np.asarray(np.arctan2(np.tan(q[..., 0]), np.cos(q[..., 1])), dtype=np.float64)


def spin_angle_gradient(q: ArrayLike) -> FloatArray:
    """Gradient of the spin angle, (dtheta/dalpha, dtheta/dbeta).

    Args:
        q: Joint positions (rad), shape (..., 2).

    Returns:
        Gradient (rad/rad), shape (..., 2).
    """
    q = _joint_array(q, "q")
    batch = _is_batch(q)
    dtheta_dalpha, dtheta_dbeta = spin_angle_gradient_entries(*_trig(q, batch))
    return _pack_vector(dtheta_dalpha, dtheta_dbeta, batch)


def mass_matrix(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Inertia matrix M(q) of Appendix A.

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        M (kg m^2), symmetric, shape (..., 2, 2).
    """
    q = _joint_array(q, "q")
    batch = _is_batch(q)
    m11, m12, m22 = _mass_entries(_trig(q, batch), params)
    return _pack_matrix(m11, m12, m12, m22, batch)


def mass_matrix_inverse(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Inverse of the inertia matrix, in closed form.

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        M^-1 (1/(kg m^2)), shape (..., 2, 2).
    """
    q = _joint_array(q, "q")
    batch = _is_batch(q)
    m11, m12, m22 = _mass_entries(_trig(q, batch), params)
    inv_det = 1.0 / (m11 * m22 - m12 * m12)
    off_diagonal = -m12 * inv_det
    return _pack_matrix(m22 * inv_det, off_diagonal, off_diagonal, m11 * inv_det, batch)


def mass_matrix_gradient(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Exact partial derivatives of M with respect to q.

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        dM/dq (kg m^2/rad), shape (..., 2, 2, 2); element [..., k, i, j] is dM_ij/dq_k.
    """
    q = _joint_array(q, "q")
    batch = _is_batch(q)
    d11_a, d12_a, d22_a, d11_b, d12_b, d22_b = mass_matrix_gradient_entries(
        *_trig(q, batch), params.I11, params.I55
    )
    return np.stack(
        (_pack_matrix(d11_a, d12_a, d12_a, d22_a, batch), _pack_matrix(d11_b, d12_b, d12_b, d22_b, batch)),
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
    qd = _joint_array(qd, "qd")
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
    q = _joint_array(q, "q")
    qd = _joint_array(qd, "qd")
    batch = _is_batch(q, qd)
    c11, c12, c21, c22 = coriolis_matrix_entries(
        *_trig(q, batch), *_components(qd, batch), params.I11, params.I55
    )
    return _pack_matrix(c11, c12, c21, c22, batch)


def _coriolis_components(
    trig: tuple[_Real, _Real, _Real, _Real], alpha_dot: _Real, beta_dot: _Real, params: SMMParameters
) -> tuple[_Real, _Real]:
    c11, c12, c21, c22 = coriolis_matrix_entries(*trig, alpha_dot, beta_dot, params.I11, params.I55)
    return c11 * alpha_dot + c12 * beta_dot, c21 * alpha_dot + c22 * beta_dot


def coriolis_vector(q: ArrayLike, qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """Coriolis/centripetal torque C(q, qd) qd.

    Args:
        q: Joint positions (rad), shape (..., 2).
        qd: Joint velocities (rad/s), shape (..., 2).
        params: Plant parameters.

    Returns:
        C qd (N m), shape (..., 2).
    """
    q = _joint_array(q, "q")
    qd = _joint_array(qd, "qd")
    batch = _is_batch(q, qd)
    return _pack_vector(*_coriolis_components(_trig(q, batch), *_components(qd, batch), params), batch)


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
    m11, m12, m22 = _mass_entries(trig, params)
    coriolis_alpha, coriolis_beta = _coriolis_components(trig, alpha_dot, beta_dot, params)
    return m11, m12, m22, coriolis_alpha, coriolis_beta, 0.0, _gravity_beta(trig[2], params)


def mass_matrix_floats(alpha: float, beta: float, params: SMMParameters) -> tuple[float, float, float]:
    """Entries of M(q) for one sample on plain floats (fast path, spin form).

    Args:
        alpha: Joint position alpha (rad).
        beta: Joint position beta (rad).
        params: Plant parameters.

    Returns:
        (M11, M12, M22) (kg m^2); M21 = M12. Equal to :func:`mass_matrix` up to rounding.
    """
    return mass_matrix_entries_spin_form(
        math.sin(alpha),
        math.cos(alpha),
        math.sin(beta),
        math.cos(beta),
        params.I11,
        params.I22,
        params.I44,
        params.I55,
    )


def rigid_body_floats(
    alpha: float, beta: float, alpha_dot: float, beta_dot: float, params: SMMParameters
) -> tuple[float, float, float, float, float, float, float]:
    """M(q), C(q, q') q' and G(q) for one sample on plain floats (fast path, spin form).

    Same quantities as :func:`rigid_body_terms`, up to rounding, at about a third of its cost.

    Args:
        alpha: Joint position alpha (rad).
        beta: Joint position beta (rad).
        alpha_dot: Joint velocity alpha' (rad/s).
        beta_dot: Joint velocity beta' (rad/s).
        params: Plant parameters.

    Returns:
        (M11, M12, M22, (C q')_alpha, (C q')_beta, G_alpha, G_beta); M in kg m^2, torques in N m.
    """
    sb = math.sin(beta)
    m11, m12, m22, coriolis_alpha, coriolis_beta = rigid_body_entries_spin_form(
        math.sin(alpha),
        math.cos(alpha),
        sb,
        math.cos(beta),
        alpha_dot,
        beta_dot,
        params.I11,
        params.I22,
        params.I44,
        params.I55,
    )
    return m11, m12, m22, coriolis_alpha, coriolis_beta, 0.0, _gravity_coefficient(params) * sb


def potential_energy(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """Gravity potential V = gravity_sign m_c l_c g cos(beta).

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters.

    Returns:
        V (J), shape q.shape[:-1].
    """
    q = _joint_array(q, "q")
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
    q = _joint_array(q, "q")
    batch = _is_batch(q)
    _, beta = _components(q, batch)
    if batch:
        sb = np.sin(beta)
        return _pack_vector(np.zeros_like(sb), _gravity_beta(sb, params), batch)
    return _pack_vector(0.0, _gravity_beta(math.sin(beta), params), batch)


def _sign(value: _Real) -> _Real:
    """sign(value) with sign(0) = 0: -1.0, 0.0 or +1.0 (a float, or an array for an array)."""
    if type(value) is float:
        return 1.0 if value > 0.0 else (-1.0 if value < 0.0 else 0.0)
    return np.sign(value)


def _has_coulomb_or_offset(params: SMMParameters) -> bool:
    return params.coulomb_friction != (0.0, 0.0) or params.torque_offset != (0.0, 0.0)


def _friction_components(alpha_dot: _Real, beta_dot: _Real, params: SMMParameters) -> tuple[_Real, _Real]:
    """F(q') = f_v q' + f_c sign(q') + offset per joint (N m); the last two only when not zero."""
    friction_alpha = params.viscous_friction[0] * alpha_dot
    friction_beta = params.viscous_friction[1] * beta_dot
    if _has_coulomb_or_offset(params):
        coulomb_alpha, coulomb_beta = params.coulomb_friction
        offset_alpha, offset_beta = params.torque_offset
        friction_alpha = friction_alpha + coulomb_alpha * _sign(alpha_dot) + offset_alpha
        friction_beta = friction_beta + coulomb_beta * _sign(beta_dot) + offset_beta
    return friction_alpha, friction_beta


def friction_floats(alpha_dot: float, beta_dot: float, params: SMMParameters) -> tuple[float, float]:
    """F(q') for one sample on plain floats: f_v q' + f_c sign(q') + offset per joint (N m)."""
    return _friction_components(alpha_dot, beta_dot, params)


def friction_torque(qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """Friction F(qd) = diag(f_v) qd + diag(f_c) sign(qd) + offset, sign(0) = 0.

    Args:
        qd: Joint velocities (rad/s), shape (..., 2).
        params: Plant parameters.

    Returns:
        F (N m), shape (..., 2).
    """
    qd = _joint_array(qd, "qd")
    friction = qd * np.asarray(params.viscous_friction)
    if _has_coulomb_or_offset(params):
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
    qd = _joint_array(qd, "qd")
    return np.asarray(0.5 * np.einsum("...i,...ij,...j->...", qd, mass, qd), dtype=np.float64)


def total_energy(q: ArrayLike, qd: ArrayLike, params: SMMParameters) -> FloatArray:
    """Total mechanical energy T + V (J), shape of the broadcast batch."""
    return np.asarray(kinetic_energy(q, qd, params) + potential_energy(q, params), dtype=np.float64)


def _acceleration(
    *,
    batch: bool,
    alpha: _Real,
    beta: _Real,
    alpha_dot: _Real,
    beta_dot: _Real,
    tau: tuple[_Real, _Real],
    tau_dist: tuple[_Real, _Real] | None,
    params: SMMParameters,
    friction: bool,
) -> tuple[_Real, _Real]:
    if batch:
        trig = (np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta))
    else:
        trig = (math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta))
    m11, m12, m22 = _mass_entries(trig, params)
    coriolis_alpha, coriolis_beta = _coriolis_components(trig, alpha_dot, beta_dot, params)
    rhs_alpha = tau[0] - coriolis_alpha
    rhs_beta = tau[1] - coriolis_beta - _gravity_beta(trig[2], params)
    if friction:
        friction_alpha, friction_beta = _friction_components(alpha_dot, beta_dot, params)
        rhs_alpha = rhs_alpha - friction_alpha
        rhs_beta = rhs_beta - friction_beta
    if tau_dist is not None:
        rhs_alpha = rhs_alpha - tau_dist[0]
        rhs_beta = rhs_beta - tau_dist[1]
    inv_det = 1.0 / (m11 * m22 - m12 * m12)
    return (m22 * rhs_alpha - m12 * rhs_beta) * inv_det, (m11 * rhs_beta - m12 * rhs_alpha) * inv_det


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
    arrays = [_joint_array(q, "q"), _joint_array(qd, "qd"), _joint_array(tau, "tau")]
    if tau_dist is not None:
        arrays.append(_joint_array(tau_dist, "tau_dist"))
    batch = _is_batch(*arrays)
    alpha, beta = _components(arrays[0], batch)
    alpha_dot, beta_dot = _components(arrays[1], batch)
    disturbance = _components(arrays[3], batch) if tau_dist is not None else None
    accel = _acceleration(
        batch=batch,
        alpha=alpha,
        beta=beta,
        alpha_dot=alpha_dot,
        beta_dot=beta_dot,
        tau=_components(arrays[2], batch),
        tau_dist=disturbance,
        params=params,
        friction=friction,
    )
    return _pack_vector(*accel, batch)


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
    q = _joint_array(q, "q")
    qd = _joint_array(qd, "qd")
    qdd = _joint_array(qdd, "qdd")
    dist = _joint_array(tau_dist, "tau_dist") if tau_dist is not None else None
    batch = _is_batch(q, qd, qdd) or (dist is not None and dist.ndim > 1)
    trig = _trig(q, batch)
    alpha_dot, beta_dot = _components(qd, batch)
    alpha_ddot, beta_ddot = _components(qdd, batch)
    m11, m12, m22 = _mass_entries(trig, params)
    coriolis_alpha, coriolis_beta = _coriolis_components(trig, alpha_dot, beta_dot, params)
    tau_alpha = m11 * alpha_ddot + m12 * beta_ddot + coriolis_alpha
    tau_beta = m12 * alpha_ddot + m22 * beta_ddot + coriolis_beta + _gravity_beta(trig[2], params)
    if friction:
        friction_alpha, friction_beta = _friction_components(alpha_dot, beta_dot, params)
        tau_alpha = tau_alpha + friction_alpha
        tau_beta = tau_beta + friction_beta
    if dist is not None:
        dist_alpha, dist_beta = _components(dist, batch)
        tau_alpha = tau_alpha + dist_alpha
        tau_beta = tau_beta + dist_beta
    return _pack_vector(tau_alpha, tau_beta, batch)


def end_effector_position(q: ArrayLike, params: SMMParameters) -> FloatArray:
    """End-effector position p = L (sin b sin theta, -sin b cos theta, cos b) (Section V.B).

    It is L times the third column of the rotation matrix of eq. 1.

    Args:
        q: Joint positions (rad), shape (..., 2).
        params: Plant parameters (link_length L).

    Returns:
        p (m), shape (..., 3).
    """
    q = _joint_array(q, "q")
    theta = spin_angle(q)
    sb = np.sin(q[..., 1])
    length = params.link_length
    return np.stack(
        (length * sb * np.sin(theta), -length * sb * np.cos(theta), length * np.cos(q[..., 1])), axis=-1
    )


def rk4_step(
    q: ArrayLike,
    qd: ArrayLike,
    tau: ArrayLike,
    dt: float,
    params: SMMParameters,
    *,
    tau_dist: ArrayLike | None = None,
    friction: bool = True,
) -> tuple[FloatArray, FloatArray]:
    """One classical fixed-step Runge-Kutta 4 step of eq. 2, holding tau and tau_dist constant.

    Args:
        q: Joint positions (rad), shape (..., 2).
        qd: Joint velocities (rad/s), shape (..., 2).
        tau: Applied torque (N m), shape (..., 2), constant over the step.
        dt: Step length (s), > 0.
        params: Plant parameters.
        tau_dist: External disturbance torque (N m), shape (..., 2), constant over the step; None for zero.
        friction: Whether to include the friction F(qd) (viscous, Coulomb and offset).

    Returns:
        (q_next, qd_next), each shape (..., 2) (rad, rad/s).
    """
    _check_step(dt)
    arrays = [_joint_array(q, "q"), _joint_array(qd, "qd"), _joint_array(tau, "tau")]
    if tau_dist is not None:
        arrays.append(_joint_array(tau_dist, "tau_dist"))
    batch = _is_batch(*arrays)
    a0, b0 = _components(arrays[0], batch)
    ad0, bd0 = _components(arrays[1], batch)
    torque = _components(arrays[2], batch)
    disturbance = _components(arrays[3], batch) if tau_dist is not None else None

    def accel(a: _Real, b: _Real, ad: _Real, bd: _Real) -> tuple[_Real, _Real]:
        return _acceleration(
            batch=batch,
            alpha=a,
            beta=b,
            alpha_dot=ad,
            beta_dot=bd,
            tau=torque,
            tau_dist=disturbance,
            params=params,
            friction=friction,
        )

    a1, b1, ad1, bd1 = rk4_stages(accel, (a0, b0, ad0, bd0), dt)
    return _pack_vector(a1, b1, batch), _pack_vector(ad1, bd1, batch)


def _check_step(dt: float) -> None:
    if not dt > 0.0 or not math.isfinite(dt):
        raise ValueError(f"dt must be a finite number > 0 s, got {dt!r}")


def rk4_stages(
    accel: Callable[[_Real, _Real, _Real, _Real], tuple[_Real, _Real]],
    state: tuple[_Real, _Real, _Real, _Real],
    dt: float,
) -> tuple[_Real, _Real, _Real, _Real]:
    """Classical RK4 of state = (alpha, beta, alpha', beta') with (alpha'', beta'') = accel(*state)."""
    a0, b0, ad0, bd0 = state
    half = 0.5 * dt
    add1, bdd1 = accel(a0, b0, ad0, bd0)
    ad2, bd2 = ad0 + half * add1, bd0 + half * bdd1
    add2, bdd2 = accel(a0 + half * ad0, b0 + half * bd0, ad2, bd2)
    ad3, bd3 = ad0 + half * add2, bd0 + half * bdd2
    add3, bdd3 = accel(a0 + half * ad2, b0 + half * bd2, ad3, bd3)
    ad4, bd4 = ad0 + dt * add3, bd0 + dt * bdd3
    add4, bdd4 = accel(a0 + dt * ad3, b0 + dt * bd3, ad4, bd4)
    sixth = dt / 6.0
    a1 = a0 + sixth * (ad0 + 2.0 * ad2 + 2.0 * ad3 + ad4)
    b1 = b0 + sixth * (bd0 + 2.0 * bd2 + 2.0 * bd3 + bd4)
    ad1 = ad0 + sixth * (add1 + 2.0 * add2 + 2.0 * add3 + add4)
    bd1 = bd0 + sixth * (bdd1 + 2.0 * bdd2 + 2.0 * bdd3 + bdd4)
    return a1, b1, ad1, bd1


def forward_dynamics_floats(
    state: tuple[float, float, float, float],
    torque: tuple[float, float],
    params: SMMParameters,
    *,
    disturbance: tuple[float, float] = (0.0, 0.0),
    friction: bool = True,
) -> tuple[float, float]:
    """Joint accelerations of eq. 2 for one sample on plain floats (fast path, spin form).

    Same as :func:`forward_dynamics` up to rounding.

    Args:
        state: (alpha, beta, alpha', beta') (rad, rad/s).
        torque: Applied torque (tau_alpha, tau_beta) (N m).
        params: Plant parameters.
        disturbance: External disturbance torque (alpha, beta) (N m).
        friction: Whether to include the friction F(qd) (viscous, Coulomb and offset).

    Returns:
        (alpha'', beta'') (rad/s^2).
    """
    alpha, beta, alpha_dot, beta_dot = state
    friction_alpha, friction_beta = (
        _friction_components(alpha_dot, beta_dot, params) if friction else (0.0 * alpha_dot, 0.0 * beta_dot)
    )
    sb = math.sin(beta)
    return forward_dynamics_entries_spin_form(
        math.sin(alpha),
        math.cos(alpha),
        sb,
        math.cos(beta),
        alpha_dot,
        beta_dot,
        torque[0] - disturbance[0] - friction_alpha,
        torque[1] - disturbance[1] - _gravity_coefficient(params) * sb - friction_beta,
        params.I11,
        params.I22,
        params.I44,
        params.I55,
    )


def rk4_step_floats(
    state: tuple[float, float, float, float],
    torque: tuple[float, float],
    dt: float,
    params: SMMParameters,
    *,
    disturbance: tuple[float, float] = (0.0, 0.0),
    friction: bool = True,
) -> tuple[float, float, float, float]:
    """One RK4 step of eq. 2 for one sample on plain floats (fast path of :func:`rk4_step`).

    The same classical scheme as :func:`rk4_step` on the spin form of the model, with the four
    evaluations written out in one generated function: equal to it up to rounding, several times
    faster. The torques are held constant over the step.

    Args:
        state: (alpha, beta, alpha', beta') (rad, rad/s).
        torque: Applied torque (tau_alpha, tau_beta) (N m).
        dt: Step length (s), > 0.
        params: Plant parameters.
        disturbance: External disturbance torque (alpha, beta) (N m).
        friction: Whether to include the friction F(qd) (viscous, Coulomb and offset).

    Returns:
        (alpha, beta, alpha', beta') after the step (rad, rad/s).
    """
    _check_step(dt)
    if friction and params.coulomb_friction != (0.0, 0.0):
        # sign(q') is not in the generated step: the same stages on the float forward dynamics.
        def accel(a: _Real, b: _Real, ad: _Real, bd: _Real) -> tuple[_Real, _Real]:
            return forward_dynamics_floats((a, b, ad, bd), torque, params, disturbance=disturbance)

        return rk4_stages(accel, state, dt)
    alpha, beta, alpha_dot, beta_dot = state
    friction_alpha, friction_beta = params.viscous_friction if friction else (0.0, 0.0)
    offset_alpha, offset_beta = params.torque_offset if friction else (0.0, 0.0)
    return rk4_step_spin_form(  # type: ignore[return-value]
        alpha,
        beta,
        alpha_dot,
        beta_dot,
        torque[0] - disturbance[0] - offset_alpha,
        torque[1] - disturbance[1] - offset_beta,
        friction_alpha,
        friction_beta,
        _gravity_coefficient(params),
        dt,
        params.I11,
        params.I22,
        params.I44,
        params.I55,
    )
