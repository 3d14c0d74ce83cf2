"""Classical fixed-step Runge-Kutta 4 of eq. 2 on arrays, and its stages for any acceleration function."""

from __future__ import annotations

import math
from collections.abc import Callable

from numpy.typing import ArrayLike

from smm_dynamics._arrays import FloatArray, Real, components, is_batch, joint_array, pack_vector
from smm_dynamics._terms import acceleration
from smm_dynamics.parameters import SMMParameters

__all__ = [
    "check_step",
    "rk4_stages",
    "rk4_step",
]


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
    check_step(dt)
    arrays = [joint_array(q, "q"), joint_array(qd, "qd"), joint_array(tau, "tau")]
    if tau_dist is not None:
        arrays.append(joint_array(tau_dist, "tau_dist"))
    batch = is_batch(*arrays)
    a0, b0 = components(arrays[0], batch)
    ad0, bd0 = components(arrays[1], batch)
    torque = components(arrays[2], batch)
    disturbance = components(arrays[3], batch) if tau_dist is not None else None

    def accel(a: Real, b: Real, ad: Real, bd: Real) -> tuple[Real, Real]:
        return acceleration(
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
    return pack_vector(a1, b1, batch), pack_vector(ad1, bd1, batch)


def check_step(dt: float) -> None:
    """Refuses a step length that is not a finite number > 0 s (ValueError)."""
    if not dt > 0.0 or not math.isfinite(dt):
        raise ValueError(f"dt must be a finite number > 0 s, got {dt!r}")


def rk4_stages(
    accel: Callable[[Real, Real, Real, Real], tuple[Real, Real]],
    state: tuple[Real, Real, Real, Real],
    dt: float,
) -> tuple[Real, Real, Real, Real]:
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
