"""The terms of eq. 2 on a float or an array (Appendix A's closed forms), shared by the model's forms."""

from __future__ import annotations

import math

import numpy as np

from smm_dynamics._arrays import Real
from smm_dynamics._generated import coriolis_matrix_entries, mass_matrix_entries
from smm_dynamics.parameters import SMMParameters


def mass_entries(trig: tuple[Real, Real, Real, Real], params: SMMParameters) -> tuple[Real, ...]:
    return mass_matrix_entries(*trig, params.I11, params.I22, params.I44, params.I55)


def gravity_coefficient(params: SMMParameters) -> float:
    # V = s m_c l_c g cos(beta) depends on beta only, so G = (0, dV/dbeta) = (0, coefficient sin(beta)).
    return -params.gravity_sign * params.mass_lever * params.gravity


def gravity_beta(sb: Real, params: SMMParameters) -> Real:
    return gravity_coefficient(params) * sb


def coriolis_components(
    trig: tuple[Real, Real, Real, Real], alpha_dot: Real, beta_dot: Real, params: SMMParameters
) -> tuple[Real, Real]:
    c11, c12, c21, c22 = coriolis_matrix_entries(*trig, alpha_dot, beta_dot, params.I11, params.I55)
    return c11 * alpha_dot + c12 * beta_dot, c21 * alpha_dot + c22 * beta_dot


def sign(value: Real) -> Real:
    """The sign of ``value``, 0 at 0: -1.0, 0.0 or +1.0 (a float, or an array for an array)."""
    if type(value) is float:
        return 1.0 if value > 0.0 else (-1.0 if value < 0.0 else 0.0)
    return np.sign(value)


def has_coulomb_or_offset(params: SMMParameters) -> bool:
    return params.coulomb_friction != (0.0, 0.0) or params.torque_offset != (0.0, 0.0)


def friction_components(alpha_dot: Real, beta_dot: Real, params: SMMParameters) -> tuple[Real, Real]:
    """F(q') = f_v q' + f_c sign(q') + offset per joint (N m); the last two only when not zero."""
    friction_alpha = params.viscous_friction[0] * alpha_dot
    friction_beta = params.viscous_friction[1] * beta_dot
    if has_coulomb_or_offset(params):
        coulomb_alpha, coulomb_beta = params.coulomb_friction
        offset_alpha, offset_beta = params.torque_offset
        friction_alpha = friction_alpha + coulomb_alpha * sign(alpha_dot) + offset_alpha
        friction_beta = friction_beta + coulomb_beta * sign(beta_dot) + offset_beta
    return friction_alpha, friction_beta


def acceleration(
    *,
    batch: bool,
    alpha: Real,
    beta: Real,
    alpha_dot: Real,
    beta_dot: Real,
    tau: tuple[Real, Real],
    tau_dist: tuple[Real, Real] | None,
    params: SMMParameters,
    friction: bool,
) -> tuple[Real, Real]:
    if batch:
        trig = (np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta))
    else:
        trig = (math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta))
    m11, m12, m22 = mass_entries(trig, params)
    coriolis_alpha, coriolis_beta = coriolis_components(trig, alpha_dot, beta_dot, params)
    rhs_alpha = tau[0] - coriolis_alpha
    rhs_beta = tau[1] - coriolis_beta - gravity_beta(trig[2], params)
    if friction:
        friction_alpha, friction_beta = friction_components(alpha_dot, beta_dot, params)
        rhs_alpha = rhs_alpha - friction_alpha
        rhs_beta = rhs_beta - friction_beta
    if tau_dist is not None:
        rhs_alpha = rhs_alpha - tau_dist[0]
        rhs_beta = rhs_beta - tau_dist[1]
    inv_det = 1.0 / (m11 * m22 - m12 * m12)
    return (m22 * rhs_alpha - m12 * rhs_beta) * inv_det, (m11 * rhs_beta - m12 * rhs_alpha) * inv_det
