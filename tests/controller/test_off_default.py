"""Formulas whose parameters the defaults hide, at non-default values against hand-computed references.

Each default below makes two quantities equal or a term vanish (phase 0, initial 0, boundary layer 1,
unclamped output, velocities 0 at the first observer steps, ...), so a mix-up between them would pass
every test run at the defaults (issue #16). TD eq. 25 with h != t is in test_td.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from smm_controller.baselines import PIDConfig, PIDController
from smm_controller.fleso import FLESO, FLESOConfig, observer_gains
from smm_controller.fpdeso import robust_switch
from smm_controller.fuzzy_batch import evaluate_system
from smm_controller.model import NominalModel
from smm_controller.reference import RampHoldReference, SineReference
from smm_controller.rules import fleso_bandwidth_system

from smm_dynamics import SMMParameters, coriolis_vector, gravity_vector, mass_matrix

DT = 0.001
PARAMS = SMMParameters()


@pytest.mark.parametrize(
    ("x", "phi", "expected"), [(0.2, 0.5, 0.4), (-0.1, 0.25, -0.4), (-0.3, 0.25, -1.0), (0.3, 0.25, 1.0)]
)
def test_boundary_layer_divides_by_phi(x: float, phi: float, expected: float) -> None:
    """sat(x / phi) with phi != 1 (the only other tested width is 1, where x / phi = x phi)."""
    assert robust_switch(x, phi) == pytest.approx(expected, rel=1e-15)


def test_sine_with_phase_per_joint() -> None:
    """q_d = A sin(w t + phase): at w t = 0.5 with phases 0.3 and -0.5 (by hand)."""
    reference = SineReference(amplitude=(0.4, -1.2), angular_frequency=2.0, phase=(0.3, -0.5))
    position, velocity, acceleration = reference.rows(0.25)
    assert position == pytest.approx((0.4 * math.sin(0.8), 0.0), abs=1e-15)
    assert velocity == pytest.approx((0.8 * math.cos(0.8), -2.4), rel=1e-15)
    assert acceleration == pytest.approx((-1.6 * math.sin(0.8), 0.0), abs=1e-15)


@pytest.mark.parametrize(
    ("profile", "position", "velocity", "acceleration"),
    [
        # x = 0.25, span = target - initial = (0.4, -0.5), ramp 0.4 s.
        ("linear", (0.2, 0.175), (1.0, -1.25), (0.0, 0.0)),
        # s = x^3 (10 - 15 x + 6 x^2) = 0.103515625, s' = 30 x^2 (1 - x)^2 = 1.0546875,
        # s'' = 60 x (1 - x)(1 - 2 x) = 5.625; velocity = span s' / 0.4, acceleration = span s'' / 0.16.
        ("quintic", (0.14140625, 0.2482421875), (1.0546875, -1.318359375), (14.0625, -17.578125)),
    ],
)
def test_ramp_from_a_non_zero_start_at_a_quarter(
    profile: str,
    position: tuple[float, float],
    velocity: tuple[float, float],
    acceleration: tuple[float, float],
) -> None:
    reference = RampHoldReference(
        target=(0.5, -0.2), ramp_time=0.4, start_time=0.1, initial=(0.1, 0.3), profile=profile
    )
    rows = reference.rows(0.2)
    assert_allclose(rows, [position, velocity, acceleration], rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("t", [0.0, 0.1, 0.5, 0.7])
def test_linear_ramp_is_at_rest_outside_the_ramp(t: float) -> None:
    reference = RampHoldReference(target=(0.5, -0.2), ramp_time=0.4, start_time=0.1, profile="linear")
    assert reference.rows(t)[1] == (0.0, 0.0)


def test_pid_conditional_integration_with_a_small_error_and_a_derivative() -> None:
    """Output clamped at 0.5 N m while e = 0.01, 0.011 rad (e * output < 1): the integral is held at 0.

    Step 2: D = k_d N (0.011 - 0.01) / (1 + N dt) = 1000 * 0.001 / 2 = 0.5, P = 0.66, so the unclamped
    output is 1.16 and the torque the clamp, 0.5.
    """
    config = PIDConfig(
        kp=(60.0, 60.0),
        ki=(10.0, 10.0),
        kd=(1.0, 1.0),
        derivative_filter=(1000.0, 1000.0),
        output_limit=(0.5, 0.5),
    )
    controller = PIDController(config)
    zero = np.zeros(2)
    tau = controller.step(np.array([[0.01, -0.01], [0.0, 0.0], [0.0, 0.0]]), zero, zero, zero, DT)
    assert list(tau) == [0.5, -0.5]
    assert list(controller.internals["i"]) == [0.0, 0.0]
    tau = controller.step(np.array([[0.011, -0.011], [0.0, 0.0], [0.0, 0.0]]), zero, zero, zero, DT)
    assert list(tau) == [0.5, -0.5]
    internals = controller.internals
    assert list(internals["i"]) == [0.0, 0.0]
    assert_allclose(internals["p"], [0.66, -0.66], rtol=1e-14)
    assert_allclose(internals["d"], [0.5, -0.5], rtol=1e-12)
    assert_allclose(internals["e"], [0.011, -0.011], rtol=1e-15)


def test_model_memo_is_keyed_on_both_angles() -> None:
    model = NominalModel(PARAMS)
    m11 = model.mass(0.1, 0.2)[0]
    for a, b in [(0.1, 0.5), (0.4, 0.5), (0.4, 0.2), (0.2, 0.2), (0.1, 0.2), (0.1, m11)]:
        assert model.mass(a, b) == NominalModel(PARAMS).mass(a, b), (a, b)
        assert model.bias(a, b, 0.3, -0.2)[:3] == model.mass(a, b)


def test_model_rejects_other_parameters_naming_their_type() -> None:
    for make in (NominalModel, NominalModel.shared):
        with pytest.raises(ValueError, match="must be SMMParameters, got float"):
            make(math.pi)  # type: ignore[arg-type]


def test_pid_integrates_when_the_output_is_exactly_at_its_limit() -> None:
    """Conditional integration starts beyond the limit: at P + I = 0.25 + 0.25 = limit I still grows.

    kp 0.5, ki 1, e 0.5 rad, dt 0.5 s (all exact in binary): I = 1 * 0.5 * 0.5 = 0.25, output 0.5 = limit.
    """
    controller = PIDController(
        PIDConfig(kp=(0.5, 0.5), ki=(1.0, 1.0), kd=(0.0, 0.0), output_limit=(0.5, 0.5))
    )
    zero = np.zeros(2)
    tau = controller.step(np.array([[0.5, -0.5], [0.0, 0.0], [0.0, 0.0]]), zero, zero, zero, 0.5)
    assert list(tau) == [0.5, -0.5]
    assert list(controller.internals["i"]) == [0.25, -0.25]


def reference_fleso(config: FLESOConfig, ys: np.ndarray, taus: np.ndarray) -> list[dict[str, np.ndarray]]:
    """The documented FLESO update (module docstring) in numpy with smm_dynamics and the dense rule base."""
    system = fleso_bandwidth_system(config.grid_points)
    x1, x2, x3 = ys[0].copy(), np.zeros(2), np.zeros(2)
    previous = np.zeros(2)
    out = []
    for y, tau in zip(ys[1:], taus[:-1], strict=True):
        accel = np.linalg.solve(
            mass_matrix(x1, PARAMS), tau - coriolis_vector(x1, x2, PARAMS) - gravity_vector(x1, PARAMS)
        )
        p1, p2 = x1 + DT * x2, x2 + DT * (x3 + accel)
        error = y - p1
        rate = (error - previous) / DT
        previous = error
        s = np.clip(np.array(config.k_s1) * error + np.array(config.k_s2) * rate, -1.0, 1.0)
        f = np.array([evaluate_system(system, (v,))[0] for v in s])
        w = np.maximum(np.array(config.w0) + np.array(config.k_w) * f, np.array(config.w_min))
        l1, l2, l3 = observer_gains(w)  # type: ignore[arg-type]
        x1, x2, x3 = p1 + DT * l1 * error, p2 + DT * l2 * error, x3 + DT * l3 * error
        out.append(
            {
                "x1_hat": x1,
                "x2_hat": x2,
                "x3_hat": x3,
                "estimation_error": error,
                "bandwidth": w,
                "estimation_error_rate": rate,
                "fuzzy_input": s,
                "xi_tilde": -mass_matrix(y, PARAMS) @ x3,
            }
        )
    return out


@pytest.mark.parametrize(
    "config",
    [
        FLESOConfig(),
        FLESOConfig(w0=(12.0, 30.0), k_w=(15.0, 25.0), k_s1=(20.0, 8.0), k_s2=(0.5, 2.0), w_min=(4.0, 9.0)),
    ],
)
def test_fleso_follows_the_documented_update_while_moving(config: FLESOConfig) -> None:
    """Steps with non-zero velocity estimates (so C(x1^, x2^) x2^ enters) against an independent update."""
    k = np.arange(40)
    ys = np.stack(
        [0.3 * np.sin(25.0 * k * DT) + 0.002 * np.cos(300.0 * k * DT), -0.2 + 0.4 * (k * DT) ** 2], axis=1
    )
    taus = np.stack([0.5 * np.cos(7.0 * k * DT), 0.2 + 0.3 * np.sin(11.0 * k * DT)], axis=1)
    fleso = FLESO(config, PARAMS)
    fleso.step(ys[0], taus[0], DT)
    expected = reference_fleso(config, ys, taus)
    for step, (y, tau) in enumerate(zip(ys[1:], taus[:-1], strict=True)):
        fleso.step(y, tau, DT)
        for key, value in expected[step].items():
            scale = 1.0 + np.abs(value).max()
            assert_allclose(
                fleso.internals[key], value, rtol=1e-9, atol=1e-9 * scale, err_msg=f"{key} step {step}"
            )
    assert np.abs(expected[-1]["x2_hat"]).min() > 1e-3  # the velocity estimates are really non-zero


def test_fleso_first_step_internals() -> None:
    """First step: x1^ = y, E = E' = s = 0, w = w0, xi~ = 0 (documented initialisation)."""
    config = FLESOConfig(w0=(12.0, 30.0))
    fleso = FLESO(config, PARAMS)
    fleso.step([0.2, -0.1], [0.3, 0.1], DT)
    internals = fleso.internals
    expected = {"x1_hat": [0.2, -0.1], "bandwidth": [12.0, 30.0]}
    for key, value in internals.items():
        assert list(value) == expected.get(key, [0.0, 0.0]), key
