"""PID (backward Euler, anti-windup), NPD (eq. 38-40) and FPD baselines."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import assume, event, given, settings
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


def _pair(low: float, high: float) -> st.SearchStrategy[tuple[float, float]]:
    """Per-joint floats in [low, high]; subnormals only where the range holds them."""
    joint = st.floats(low, high, allow_subnormal=low <= 0.0)
    return st.tuples(joint, joint)


class TestPIDConditionalIntegration:
    """Saturated output: I is held while e pushes it further out and moves by k_i e dt while e pulls it back.

    The integral is wound up inside a wide output limit, then the limit is lowered (``reconfigure`` keeps
    the integral), so the output is saturated by the integral alone and the error can take either sign.
    Gains differ per joint: alpha kp = 10, ki = 100; beta kp = 40, ki = 250; dt = 0.01 s.
    """

    H = 0.01
    WIDE = PIDConfig(kp=(10.0, 40.0), ki=(100.0, 250.0), kd=(0.0, 0.0), output_limit=(5.0, 7.0))
    NARROW = PIDConfig(kp=(10.0, 40.0), ki=(100.0, 250.0), kd=(0.0, 0.0), output_limit=(1.0, 1.5))

    def wound_up(self) -> PIDController:
        """Ten steps at e = (0.2, -0.1) inside (5, 7): I = (0.2, -0.25) per step, then the limit (1, 1.5)."""
        controller = PIDController(self.WIDE)
        for k in range(1, 11):
            tau = controller.step(reference((0.2, -0.1)), ZERO, ZERO, ZERO, self.H)
            # Inside the limit with e pushing outwards: I moves (the |u| > limit half of the rule).
            assert_allclose(controller.internals["i"], [0.2 * k, -0.25 * k], rtol=1e-12)
        assert_allclose(tau, [2.0 + 2.0, -4.0 - 2.5], rtol=1e-12)
        controller.reconfigure(self.NARROW)
        return controller

    def test_integral_held_while_saturated_and_the_error_pushes_further(self) -> None:
        controller = self.wound_up()
        wound = controller.internals["i"].copy()
        for _ in range(5):
            # alpha: p = 0.5, candidate I = 2.05, u = 2.55 > 1; beta: p = -0.8, I = -2.55, u = -3.35 < -1.5.
            tau = controller.step(reference((0.05, -0.02)), ZERO, ZERO, ZERO, self.H)
            assert_allclose(tau, [1.0, -1.5], atol=0)
            assert_allclose(controller.internals["i"], wound, atol=0)
        assert_allclose(wound, [2.0, -2.5], rtol=1e-12)

    def test_integral_moves_while_saturated_and_the_error_pulls_back(self) -> None:
        controller = self.wound_up()
        for k in range(1, 4):
            # alpha: e = -0.05, I = 2 - 0.05 k, u = 1.5 - 0.05 k > 1; beta: e = 0.02, I = -2.5 + 0.05 k,
            # u = -1.7 + 0.05 k < -1.5: both still saturated, against the error.
            tau = controller.step(reference((-0.05, 0.02)), ZERO, ZERO, ZERO, self.H)
            assert_allclose(tau, [1.0, -1.5], atol=0)
            assert_allclose(controller.internals["i"], [2.0 - 0.05 * k, -2.5 + 0.05 * k], rtol=1e-12)
            unclamped = controller.internals["p"] + controller.internals["i"]
            assert_allclose(unclamped, [1.5 - 0.05 * k, -1.7 + 0.05 * k], rtol=1e-12)

    @settings(deadline=None)
    @given(
        config=st.builds(
            PIDConfig,
            kp=_pair(0.0, 50.0),
            ki=_pair(0.1, 300.0),
            kd=_pair(0.0, 2.0),
            derivative_filter=_pair(10.0, 2000.0),
        ),
        dt=st.floats(1e-4, 1e-3, allow_subnormal=False),
        segments=st.lists(
            st.tuples(_pair(-1.0, 1.0), _pair(0.2, 5.0), st.integers(1, 40)), min_size=2, max_size=8
        ),
    )
    def test_saturated_integral_held_with_the_error_and_moves_against_it(
        self,
        config: PIDConfig,
        dt: float,
        segments: list[tuple[tuple[float, float], tuple[float, float], int]],
    ) -> None:
        """Segments of constant error, each with its output limit (reconfigured, the integral kept).

        After each step u = p + I + d (unclamped). Saturated in the error's direction (|u| > limit,
        e u > 0): I is held, so it never grows. Saturated against the error: I moved by k_i e dt. One step's
        k_i |e| dt <= 300 * 1e-3 = 0.3 stays below the output range 2 * 0.2, so holding I can never leave the
        output saturated on the side opposite to the error. Examples without both kinds of step are discarded.
        """
        controller = PIDController(config)
        held = opposed = 0
        for error, limit, repeats in segments:
            controller.reconfigure(dataclasses.replace(config, output_limit=limit))
            for _ in range(repeats):
                before = controller.internals["i"].copy()
                controller.step(reference(error), ZERO, ZERO, ZERO, dt)
                internals = controller.internals
                after = internals["i"]
                unclamped = internals["p"] + after + internals["d"]
                for j in range(2):
                    if abs(unclamped[j]) <= limit[j]:
                        continue
                    if error[j] * unclamped[j] > 0.0:
                        held += 1
                        assert after[j] == before[j], f"joint {j}: I grew while saturated with e = {error[j]}"
                    elif error[j] * unclamped[j] < 0.0:
                        opposed += 1
                        step = config.ki[j] * error[j] * dt
                        scale = 1e-15 * (abs(before[j]) + abs(step)) + np.finfo(float).tiny
                        assert after[j] == pytest.approx(before[j] + step, rel=1e-12, abs=scale), (
                            f"joint {j}: I did not move while saturated against e = {error[j]}"
                        )
        event(f"held steps: {'some' if held else 'none'}; opposed steps: {'some' if opposed else 'none'}")
        assume(held > 0 and opposed > 0)
