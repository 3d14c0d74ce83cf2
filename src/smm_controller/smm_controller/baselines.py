"""Baseline controllers of the paper (Section V.A): PID, NPD (eq. 38-40) and FPD.

All three output joint torque directly (N m), use no model, and share the FPDESO step signature (the
disturbance estimate is accepted and ignored). PID's discretisation and anti-windup: docs/DESIGN.md,
"PID discretisation".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from smm_schema.ranges import above, at_least, check_bounds

from smm_controller._validation import (
    FloatArray,
    check_instance,
    internals_view,
)
from smm_controller.fuzzy_pd import PAPER_FPD_FUZZY, FuzzyPDConfig, FuzzyPDGainSchedule
from smm_controller.torque_law import TorqueLaw

__all__ = [
    "FPDConfig",
    "FPDController",
    "NPDConfig",
    "NPDController",
    "PIDConfig",
    "PIDController",
    "npd_gain",
]


@dataclass(frozen=True)
class PIDConfig:
    """PID gains per joint (alpha, beta); defaults are the paper's (Section V.A, item 2).

    Attributes:
        kp: Proportional gain (N m/rad), >= 0.
        ki: Integral gain (N m/(rad s)), >= 0.
        kd: Derivative gain (N m s/rad), >= 0.
        derivative_filter: N of k_d N s/(s + N) (rad/s), > 0.
        integrator_limit: Clamp of the integral term (N m), > 0; inf = no clamp (paper).
        output_limit: Clamp of the torque (N m), > 0; inf = none (paper). While the output is
            clamped, integration that would push it further is suspended.
    """

    kp: tuple[float, float] = field(default=(10.0, 50.0), metadata=at_least(0.0))
    ki: tuple[float, float] = field(default=(0.9, 3.0), metadata=at_least(0.0))
    kd: tuple[float, float] = field(default=(1.5, 0.5), metadata=at_least(0.0))
    derivative_filter: tuple[float, float] = field(default=(500.0, 1456.0), metadata=above(0.0))
    integrator_limit: tuple[float, float] = field(default=(math.inf, math.inf), metadata=above(0.0, inf=True))
    output_limit: tuple[float, float] = field(default=(math.inf, math.inf), metadata=above(0.0, inf=True))

    def __post_init__(self) -> None:
        check_bounds(self)


def _clamp(x: float, limit: float) -> float:
    return -limit if x < -limit else (limit if x > limit else x)


class PIDController(TorqueLaw):
    """Discrete PID with filtered derivative, integrator clamp and conditional integration.

    Args:
        config: Gains (default: the paper's).
    """

    def __init__(self, config: PIDConfig | None = None) -> None:
        self.config = config if config is not None else PIDConfig()
        self.reset()

    def reset(self) -> None:
        """Zeroes the integral and derivative states; the next step has no derivative kick."""
        self._integral = [0.0, 0.0]
        self._derivative = [0.0, 0.0]
        self._previous_error: list[float] | None = None
        self._last: tuple[float, ...] = (0.0,) * 10

    def reconfigure(self, config: PIDConfig) -> None:
        """Takes new gains for the next step and keeps the integral, derivative filter and last error.

        The integral is re-clamped to the new ``integrator_limit`` at once, so that conditional
        integration can never hold it outside the new limit.

        Args:
            config: The new gains (replaces the config whole).

        Raises:
            TypeError: ``config`` is not a :class:`PIDConfig`.
        """
        check_instance("config", config, PIDConfig)
        for j in range(2):
            self._integral[j] = _clamp(self._integral[j], config.integrator_limit[j])
        self.config = config

    def step_floats(
        self,
        reference: Sequence[Sequence[float]],
        q: tuple[float, float],
        q_dot: tuple[float, float],
        disturbance_estimate: tuple[float, float],
        dt: float,
    ) -> tuple[float, float]:
        """Same as :meth:`step` on floats (reference as nested 3x2 lists); returns (tau_a, tau_b)."""
        config = self.config
        errors = (reference[0][0] - q[0], reference[0][1] - q[1])
        previous = self._previous_error if self._previous_error is not None else list(errors)
        taus = []
        proportional = []
        for j in range(2):
            e = errors[j]
            n = config.derivative_filter[j]
            self._derivative[j] = (self._derivative[j] + config.kd[j] * n * (e - previous[j])) / (
                1.0 + n * dt
            )
            p = config.kp[j] * e
            held = self._integral[j]
            integral = _clamp(held + config.ki[j] * e * dt, config.integrator_limit[j])
            unclamped = p + integral + self._derivative[j]
            limit = config.output_limit[j]
            if abs(unclamped) > limit and e * unclamped > 0.0:
                integral = held
                unclamped = p + integral + self._derivative[j]
            self._integral[j] = integral
            proportional.append(p)
            taus.append(_clamp(unclamped, limit))
        self._previous_error = list(errors)
        self._last = (
            errors[0],
            errors[1],
            proportional[0],
            proportional[1],
            self._integral[0],
            self._integral[1],
            self._derivative[0],
            self._derivative[1],
            taus[0],
            taus[1],
        )
        return taus[0], taus[1]

    def track_saturation(
        self, unlimited: tuple[float, float], limited: tuple[float, float], dt: float
    ) -> None:
        """Back-calculation anti-windup: integral += dt (limited - unlimited) / T_t, after a limit downstream.

        T_t is control_toolbox's default tracking time: sqrt(kd / ki), or kp / ki without kd; a joint with
        ki = 0 has no integral to correct. The integral stays within ``integrator_limit``.
        """
        config = self.config
        for j in range(2):
            ki = config.ki[j]
            if ki <= 0.0:
                continue
            tracking_time = math.sqrt(config.kd[j] / ki) if config.kd[j] > 0.0 else config.kp[j] / ki
            if tracking_time <= 0.0:
                continue
            corrected = self._integral[j] + dt * (limited[j] - unlimited[j]) / tracking_time
            self._integral[j] = _clamp(corrected, config.integrator_limit[j])

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only copies, shape (2,): e (rad), p, i, d, tau (N m)."""
        return internals_view(("e", "p", "i", "d", "tau"), self._last)


@dataclass(frozen=True)
class NPDConfig:
    """Nonlinear PD gains per joint (alpha, beta); defaults are the paper's (Section V.A, item 3).

    Attributes:
        k_np: Proportional gain coefficient K_Np (N m/rad^rho_p), > 0.
        k_nd: Derivative gain coefficient K_Nd (N m s^rho_d/rad^rho_d), > 0.
        delta_p: Error threshold below which the P gain is constant (rad), > 0.
        delta_d: Error-rate threshold below which the D gain is constant (rad/s), > 0.
        rho_p: Nonlinearity exponent of the P term, > 0 (1 = linear).
        rho_d: Nonlinearity exponent of the D term, > 0 (1 = linear).
    """

    k_np: tuple[float, float] = field(default=(29.0, 20.0), metadata=above(0.0))
    k_nd: tuple[float, float] = field(default=(0.8, 0.5), metadata=above(0.0))
    delta_p: tuple[float, float] = field(default=(0.1, 0.1), metadata=above(0.0))
    delta_d: tuple[float, float] = field(default=(0.1, 0.2), metadata=above(0.0))
    rho_p: tuple[float, float] = field(default=(1.2, 0.6), metadata=above(0.0))
    rho_d: tuple[float, float] = field(default=(1.1, 0.8), metadata=above(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)


def npd_gain(x: float, coefficient: float, threshold: float, exponent: float) -> float:
    """NPD gain of eq. 39, and of eq. 40 read with |e'|.

    Args:
        x: The error e (rad) or error rate e' (rad/s).
        coefficient: k_Np or k_Nd.
        threshold: delta_p or delta_d, > 0.
        exponent: rho_p or rho_d, > 0.

    Returns:
        k |x|^(rho - 1) if |x| > delta, else k delta^(rho - 1).
    """
    magnitude = abs(x)
    if magnitude > threshold:
        return coefficient * math.pow(magnitude, exponent - 1.0)
    return coefficient * math.pow(threshold, exponent - 1.0)


class NPDController(TorqueLaw):
    """Nonlinear PD (eq. 38-40): tau = K_Np(e) e + K_Nd(e') e'.

    Args:
        config: Gains (default: the paper's).
    """

    def __init__(self, config: NPDConfig | None = None) -> None:
        self.config = config if config is not None else NPDConfig()
        self.reset()

    def reset(self) -> None:
        """The law is memoryless; this clears the recorded internals."""
        self._last: tuple[float, ...] = (0.0,) * 6

    def reconfigure(self, config: NPDConfig) -> None:
        """Takes new gains for the next step (the law is memoryless; internals kept until then).

        Args:
            config: The new gains (replaces the config whole).

        Raises:
            TypeError: ``config`` is not an :class:`NPDConfig`.
        """
        self.config = check_instance("config", config, NPDConfig)

    def step_floats(
        self,
        reference: Sequence[Sequence[float]],
        q: tuple[float, float],
        q_dot: tuple[float, float],
        disturbance_estimate: tuple[float, float],
        dt: float,
    ) -> tuple[float, float]:
        """Same as :meth:`step` on floats (reference as nested 3x2 lists); returns (tau_a, tau_b)."""
        c = self.config
        e0 = reference[0][0] - q[0]
        e1 = reference[0][1] - q[1]
        ed0 = reference[1][0] - q_dot[0]
        ed1 = reference[1][1] - q_dot[1]
        kp0 = npd_gain(e0, c.k_np[0], c.delta_p[0], c.rho_p[0])
        kp1 = npd_gain(e1, c.k_np[1], c.delta_p[1], c.rho_p[1])
        kd0 = npd_gain(ed0, c.k_nd[0], c.delta_d[0], c.rho_d[0])
        kd1 = npd_gain(ed1, c.k_nd[1], c.delta_d[1], c.rho_d[1])
        tau0 = kp0 * e0 + kd0 * ed0
        tau1 = kp1 * e1 + kd1 * ed1
        self._last = (kp0, kp1, kd0, kd1, tau0, tau1)
        return tau0, tau1

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only copies, shape (2,): kp, kd, tau (N m)."""
        return internals_view(("kp", "kd", "tau"), self._last)


@dataclass(frozen=True)
class FPDConfig:
    """FPD baseline: the fuzzy gain schedule with the paper's FPD gains (N m/rad, N m s/rad).

    Attributes:
        fuzzy: Gain schedule parameters (default: Section V.A, item 4).
    """

    fuzzy: FuzzyPDConfig = PAPER_FPD_FUZZY

    def __post_init__(self) -> None:
        if not isinstance(self.fuzzy, FuzzyPDConfig):
            raise ValueError(f"fuzzy must be a FuzzyPDConfig, got {self.fuzzy!r}")


class FPDController(TorqueLaw):
    """Fuzzy PD (eq. 11-12 without model): tau = k_p e + k_d e'.

    Args:
        config: Gains (default: the paper's FPD gains).
    """

    def __init__(self, config: FPDConfig | None = None) -> None:
        self.config = config if config is not None else FPDConfig()
        self.schedule = FuzzyPDGainSchedule(self.config.fuzzy)
        self.reset()

    def reset(self) -> None:
        """The law is memoryless; this clears the recorded internals."""
        self.schedule.reset()
        self._last: tuple[float, ...] = (0.0,) * 6

    def reconfigure(self, config: FPDConfig) -> None:
        """Takes new gains for the next step (the law is memoryless; internals kept until then).

        Args:
            config: The new gains (replaces the config whole).

        Raises:
            TypeError: ``config`` is not an :class:`FPDConfig`.
        """
        check_instance("config", config, FPDConfig)
        self.schedule.reconfigure(config.fuzzy)
        self.config = config

    def step_floats(
        self,
        reference: Sequence[Sequence[float]],
        q: tuple[float, float],
        q_dot: tuple[float, float],
        disturbance_estimate: tuple[float, float],
        dt: float,
    ) -> tuple[float, float]:
        """Same as :meth:`step` on floats (reference as nested 3x2 lists); returns (tau_a, tau_b)."""
        e0 = reference[0][0] - q[0]
        e1 = reference[0][1] - q[1]
        ed0 = reference[1][0] - q_dot[0]
        ed1 = reference[1][1] - q_dot[1]
        kp0, kp1, kd0, kd1 = self.schedule.step_floats(e0, e1, ed0, ed1)
        tau0 = kp0 * e0 + kd0 * ed0
        tau1 = kp1 * e1 + kd1 * ed1
        self._last = (kp0, kp1, kd0, kd1, tau0, tau1)
        return tau0, tau1

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only copies, shape (2,): kp, kd, tau (N m)."""
        return internals_view(("kp", "kd", "tau"), self._last)
