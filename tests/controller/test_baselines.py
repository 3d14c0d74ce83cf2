"""PID (backward Euler, anti-windup), NPD (eq. 38-40) and FPD baselines."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_controller.baselines import (
    FPDConfig,
    FPDController,
    NPDConfig,
    NPDController,
    PIDConfig,
    PIDController,
    npd_gain,
)
from smm_controller.fuzzy_pd import PAPER_FPD_FUZZY, FuzzyPDGainSchedule

DT = 0.001
ZERO = np.zeros(2)


def reference(position: tuple[float, float], velocity: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    return np.array([position, velocity, (0.0, 0.0)])


def pid(**overrides: tuple[float, float]) -> PIDController:
    fields = {"kp": (0.0, 0.0), "ki": (0.0, 0.0), "kd": (0.0, 0.0)}
    fields.update(overrides)
    return PIDController(PIDConfig(**fields))


class TestPID:
    def test_proportional(self) -> None:
        controller = pid(kp=(10.0, 50.0))
        assert_allclose(controller.step(reference((0.2, -0.1)), [0.1, 0.0], ZERO, ZERO, DT), [1.0, -5.0])

    def test_integral_accumulates_backward_euler(self) -> None:
        controller = pid(ki=(2.0, 4.0))
        for k in range(1, 11):
            tau = controller.step(reference((0.5, 0.25)), ZERO, ZERO, ZERO, DT)
            assert_allclose(tau, [2.0 * 0.5 * k * DT, 4.0 * 0.25 * k * DT], rtol=1e-12)

    def test_derivative_filter_step_response(self) -> None:
        """e jumps by 1 after the first step: D_k = k_d N / (1 + N dt)^k (backward Euler of kd N s/(s+N))."""
        kd, n = (1.5, 0.5), (500.0, 1456.0)
        controller = pid(kd=kd, derivative_filter=n)
        assert_allclose(controller.step(reference((0.0, 0.0)), ZERO, ZERO, ZERO, DT), [0.0, 0.0])
        for k in range(1, 6):
            tau = controller.step(reference((1.0, 1.0)), ZERO, ZERO, ZERO, DT)
            expected = [kd[j] * n[j] / (1.0 + n[j] * DT) ** k for j in range(2)]
            assert_allclose(tau, expected, rtol=1e-12)

    def test_no_derivative_kick_on_the_first_step(self) -> None:
        controller = pid(kd=(1.5, 0.5))
        assert_allclose(controller.step(reference((1.0, 0.785)), ZERO, ZERO, ZERO, DT), [0.0, 0.0])

    def test_integrator_clamp(self) -> None:
        controller = pid(ki=(100.0, 100.0), integrator_limit=(0.3, 0.05))
        for _ in range(100):
            tau = controller.step(reference((1.0, -1.0)), ZERO, ZERO, ZERO, DT)
        assert_allclose(tau, [0.3, -0.05])
        assert_allclose(controller.internals["i"], [0.3, -0.05])

    def test_output_limit_and_conditional_integration(self) -> None:
        controller = pid(kp=(10.0, 10.0), ki=(100.0, 100.0), output_limit=(2.0, 2.0))
        for _ in range(200):
            tau = controller.step(reference((1.0, -1.0)), ZERO, ZERO, ZERO, DT)
        assert_allclose(tau, [2.0, -2.0])
        # P alone (10) saturates, so integration that pushes further out never happened.
        assert_allclose(controller.internals["i"], [0.0, 0.0])
        # When the error reverses, the output leaves saturation at once (no wound-up integral).
        tau = controller.step(reference((-0.1, 0.1)), ZERO, ZERO, ZERO, DT)
        assert_allclose(tau, [-1.0 - 100.0 * 0.1 * DT, 1.0 + 100.0 * 0.1 * DT], rtol=1e-12)

    def test_ignores_the_disturbance_estimate(self) -> None:
        first = PIDController().step(reference((0.3, 0.2)), ZERO, ZERO, [5.0, -5.0], DT)
        second = PIDController().step(reference((0.3, 0.2)), ZERO, ZERO, ZERO, DT)
        assert_allclose(first, second, atol=0)


class TestNPD:
    @settings(deadline=None)
    @given(
        x=st.floats(-2.0, 2.0, allow_subnormal=True),
        k=st.floats(0.1, 50.0, allow_subnormal=False),
        delta=st.floats(0.01, 0.5, allow_subnormal=False),
        rho=st.floats(0.3, 2.0, allow_subnormal=False),
    )
    def test_gain_is_piecewise_eq_39(self, x: float, k: float, delta: float, rho: float) -> None:
        expected = k * abs(x) ** (rho - 1.0) if abs(x) > delta else k * delta ** (rho - 1.0)
        assert npd_gain(x, k, delta, rho) == pytest.approx(expected, rel=1e-14)

    def test_gain_is_continuous_at_the_threshold(self) -> None:
        assert npd_gain(0.1 + 1e-12, 29.0, 0.1, 1.2) == pytest.approx(npd_gain(0.1, 29.0, 0.1, 1.2), rel=1e-9)

    @pytest.mark.parametrize(("e", "e_dot"), [((0.05, 0.05), (0.05, 0.1)), ((0.5, -0.3), (-2.0, 1.5))])
    def test_law_eq_38_with_abs_error_rate(self, e: tuple[float, float], e_dot: tuple[float, float]) -> None:
        c = NPDConfig()
        tau = NPDController(c).step(reference(e, e_dot), ZERO, ZERO, ZERO, DT)
        for j in range(2):
            kp = c.k_np[j] * max(abs(e[j]), c.delta_p[j]) ** (c.rho_p[j] - 1.0)
            kd = c.k_nd[j] * max(abs(e_dot[j]), c.delta_d[j]) ** (c.rho_d[j] - 1.0)
            assert tau[j] == pytest.approx(kp * e[j] + kd * e_dot[j], rel=1e-13)

    def test_linear_when_rho_is_one(self) -> None:
        c = NPDConfig(rho_p=(1.0, 1.0), rho_d=(1.0, 1.0))
        tau = NPDController(c).step(reference((0.4, -0.2), (1.0, 0.5)), ZERO, ZERO, ZERO, DT)
        assert_allclose(tau, [29.0 * 0.4 + 0.8 * 1.0, 20.0 * -0.2 + 0.5 * 0.5])


class TestFPD:
    def test_law_is_scheduled_pd(self) -> None:
        controller = FPDController()
        e, e_dot = np.array([0.2, -0.1]), np.array([0.5, 0.3])
        tau = controller.step(np.array([e, e_dot, ZERO]), ZERO, ZERO, ZERO, DT)
        kp, kd = FuzzyPDGainSchedule(PAPER_FPD_FUZZY).step(e, e_dot)
        assert_allclose(tau, kp * e + kd * e_dot, rtol=1e-14)

    def test_uses_measured_velocity_in_the_error_rate(self) -> None:
        controller = FPDController(FPDConfig())
        tau = controller.step(np.array([[0.1, 0.1], [0.0, 0.0], [0.0, 0.0]]), ZERO, [0.4, -0.4], ZERO, DT)
        kp, kd = FuzzyPDGainSchedule(PAPER_FPD_FUZZY).step([0.1, 0.1], [-0.4, 0.4])
        assert_allclose(tau, kp * 0.1 + kd * np.array([-0.4, 0.4]), rtol=1e-14)


@pytest.mark.parametrize("controller", [PIDController(), NPDController(), FPDController()])
def test_reference_shape_is_checked(controller: PIDController | NPDController | FPDController) -> None:
    with pytest.raises(ValueError, match=r"shape \(3, 2\)"):
        controller.step(np.zeros((2, 2)), ZERO, ZERO, ZERO, DT)
    with pytest.raises(ValueError, match="reference must be finite"):
        controller.step(np.full((3, 2), math.nan), ZERO, ZERO, ZERO, DT)


def _integral_after_tracking(
    config: PIDConfig, unlimited: tuple[float, float], limited: tuple[float, float]
) -> np.ndarray:
    """The PID's integral after one step with no error and one back-calculation (shown by a second step)."""
    pid = PIDController(config)
    rest = [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
    pid.step_floats(rest, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), 1e-3)
    pid.track_saturation(unlimited, limited, 0.01)
    pid.step_floats(rest, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), 1e-3)
    return np.asarray(pid.internals["i"])


def test_back_calculation_tracking_time_by_hand() -> None:
    # Joint alpha with kd: T_t = sqrt(kd / ki) = sqrt(8 / 2) = 2 s; beta without kd: T_t = kp / ki = 5 s.
    config = PIDConfig(kp=(1.0, 10.0), ki=(2.0, 2.0), kd=(8.0, 0.0))
    integral = _integral_after_tracking(config, (7.0, -7.0), (3.0, -3.0))
    assert_allclose(integral, [0.01 * (3.0 - 7.0) / 2.0, 0.01 * (-3.0 + 7.0) / 5.0], rtol=1e-12)


def test_back_calculation_skips_a_joint_without_integral_or_tracking_time_and_goes_on() -> None:
    # alpha: ki = 0 (no integral to correct); beta corrected with T_t = kp / ki = 1 s.
    no_integral = PIDConfig(kp=(1.0, 1.0), ki=(0.0, 1.0), kd=(0.0, 0.0))
    assert_allclose(_integral_after_tracking(no_integral, (5.0, 5.0), (1.0, 1.0)), [0.0, -0.04], rtol=1e-12)
    # alpha: kp = kd = 0 gives T_t = 0 (pure I: nothing to track with); beta as above.
    pure_integral = PIDConfig(kp=(0.0, 1.0), ki=(1.0, 1.0), kd=(0.0, 0.0))
    assert_allclose(_integral_after_tracking(pure_integral, (5.0, 5.0), (1.0, 1.0)), [0.0, -0.04], rtol=1e-12)
