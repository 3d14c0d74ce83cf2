"""compensate_friction: FPDESO's feedforward and the FLESO's model carry the model's F(q') only when asked."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.testing import assert_allclose
from smm_controller.fleso import FLESO, FLESOConfig
from smm_controller.fpdeso import FPDESOConfig, FPDESOController

from smm_dynamics import SMMParameters, friction_torque, gravity_vector, rk4_step

DT = 0.001
FRICTIONAL = SMMParameters(
    viscous_friction=(0.3, 0.2), coulomb_friction=(0.15, 0.25), torque_offset=(0.05, -0.1)
)
REFERENCE = [[0.3, -0.2], [0.5, -0.4], [1.0, 2.0]]


@pytest.mark.parametrize("q_dot", [(0.4, -0.7), (0.0, 0.3), (-1.0, 0.0)])
def test_fpdeso_feedforward_gains_exactly_the_model_friction(q_dot: tuple[float, float]) -> None:
    plain = FPDESOController(None, FRICTIONAL)
    compensating = FPDESOController(FPDESOConfig(compensate_friction=True), FRICTIONAL)
    q, xi = (0.25, -0.15), (0.02, -0.03)
    tau_plain = plain.step_floats(REFERENCE, q, q_dot, xi, DT)
    tau_comp = compensating.step_floats(REFERENCE, q, q_dot, xi, DT)
    friction = friction_torque(np.array(q_dot), FRICTIONAL)
    assert_allclose(np.subtract(tau_comp, tau_plain), friction, rtol=1e-12, atol=1e-14)
    assert_allclose(
        compensating.internals["feedforward"] - plain.internals["feedforward"],
        friction,
        rtol=1e-12,
        atol=1e-14,
    )


def test_fpdeso_default_ignores_friction() -> None:
    """Off by default: the paper's law does not see the model's friction."""
    assert FPDESOConfig().compensate_friction is False
    frictionless = dataclasses.replace(
        FRICTIONAL, viscous_friction=(0.0, 0.0), coulomb_friction=(0.0, 0.0), torque_offset=(0.0, 0.0)
    )
    args = (REFERENCE, (0.25, -0.15), (0.4, -0.7), (0.0, 0.0), DT)
    assert FPDESOController(None, FRICTIONAL).step_floats(*args) == FPDESOController(
        None, frictionless
    ).step_floats(*args)


@pytest.mark.parametrize("field", ["compensate_friction"])
def test_non_bool_is_rejected(field: str) -> None:
    with pytest.raises(ValueError, match=rf"^{field} must be a bool"):
        FPDESOConfig(**{field: 1})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=rf"^{field} must be a bool"):
        FLESOConfig(**{field: "yes"})  # type: ignore[arg-type]


def _estimate_at_rest(config: FLESOConfig) -> np.ndarray:
    """xi~ after 4 s with the plant (equal to the model) held still by gravity compensation."""
    fleso = FLESO(config, FRICTIONAL)
    q, qd = np.array([0.1, -0.1]), np.zeros(2)
    tau_applied = np.zeros(2)
    xi = np.zeros(2)
    for _ in range(4000):
        xi = fleso.step(q, tau_applied, DT)
        tau_applied = gravity_vector(q, FRICTIONAL) + np.array(FRICTIONAL.torque_offset)
        q, qd = rk4_step(q, qd, tau_applied, DT, FRICTIONAL)
    return np.asarray(xi)


def test_fleso_with_the_model_friction_estimates_no_disturbance() -> None:
    """The plant's only unmodelled torque is its offset: the plain FLESO sees it, the compensating one not."""
    assert_allclose(_estimate_at_rest(FLESOConfig()), FRICTIONAL.torque_offset, atol=1e-9)
    assert_allclose(_estimate_at_rest(FLESOConfig(compensate_friction=True)), (0.0, 0.0), atol=1e-9)
