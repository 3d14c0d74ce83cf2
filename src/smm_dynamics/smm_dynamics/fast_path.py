"""The model's plain-float fast path for one sample (spin form; equal to the array model up to rounding).

Costs and forms: docs/DYNAMICS.md.
"""

from __future__ import annotations

import math

from smm_dynamics._arrays import Real
from smm_dynamics._generated import (
    forward_dynamics_entries_spin_form,
    mass_matrix_entries_spin_form,
    rigid_body_entries_spin_form,
    rk4_step_spin_form,
)
from smm_dynamics._terms import friction_components, gravity_coefficient
from smm_dynamics.integration import check_step, rk4_stages
from smm_dynamics.parameters import SMMParameters

__all__ = [
    "forward_dynamics_floats",
    "friction_floats",
    "mass_matrix_floats",
    "rigid_body_floats",
    "rk4_step_floats",
]


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
    return m11, m12, m22, coriolis_alpha, coriolis_beta, 0.0, gravity_coefficient(params) * sb


def friction_floats(alpha_dot: float, beta_dot: float, params: SMMParameters) -> tuple[float, float]:
    """F(q') for one sample on plain floats: f_v q' + f_c sign(q') + offset per joint (N m)."""
    return friction_components(alpha_dot, beta_dot, params)


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
        friction_components(alpha_dot, beta_dot, params) if friction else (0.0 * alpha_dot, 0.0 * beta_dot)
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
        torque[1] - disturbance[1] - gravity_coefficient(params) * sb - friction_beta,
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
    check_step(dt)
    if friction and params.coulomb_friction != (0.0, 0.0):
        # sign(q') is not in the generated step: the same stages on the float forward dynamics.
        def accel(a: Real, b: Real, ad: Real, bd: Real) -> tuple[Real, Real]:
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
        gravity_coefficient(params),
        dt,
        params.I11,
        params.I22,
        params.I44,
        params.I55,
    )
