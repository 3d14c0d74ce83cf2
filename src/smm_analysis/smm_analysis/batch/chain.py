"""The control chain of ``smm_controller`` (TD -> FLESO -> law -> output limits) for N runs at once.

Each class is the array form of its scalar class, same expressions in the same order, one row per run
(joint arrays (N, 2)); the scalar classes stay the reference the tests hold these against.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from smm_controller.fuzzy_pd import FuzzyPDConfig
from smm_controller.laws import batched_twin, get_law
from smm_controller.limits import OutputLimitConfig
from smm_dynamics.spin_form import mass_matrix_entries_spin_form, rigid_body_entries_spin_form

from smm_analysis.batch.fuzzy import BandwidthFuzzy, PDGainFuzzy
from smm_controller import (
    FLESOConfig,
    FPDConfig,
    FPDESOConfig,
    NPDConfig,
    PIDConfig,
    TrackingDifferentiatorConfig,
)
from smm_dynamics import SMMParameters

__all__ = [
    "BatchChain",
    "BatchFLESO",
    "BatchLaw",
    "BatchLimiter",
    "BatchModel",
    "BatchTD",
    "make_batch_law",
    "pairs",
]

FloatArray = NDArray[np.float64]
Reference = tuple[FloatArray, FloatArray, FloatArray]
"""q_d, q_d', q_d'' of every run, each (N, 2)."""


def pairs(configs: Sequence[Any], get: Callable[[Any], tuple[float, float]]) -> FloatArray:
    """The per-joint field ``get(config)`` of every config, shape (N, 2)."""
    return np.array([get(config) for config in configs], dtype=np.float64).reshape(len(configs), 2)


def _fields(configs: Sequence[Any], names: Sequence[str]) -> list[FloatArray]:
    """The per-joint fields ``names`` of every config, each (N, 2)."""
    return [pairs(configs, operator.attrgetter(name)) for name in names]


def _same(configs: Sequence[Any], get: Callable[[Any], Any], what: str) -> Any:
    values = {get(config) for config in configs}
    if len(values) != 1:
        raise ValueError(f"every run of a batch needs the same {what}, got {sorted(values)!r}")
    return values.pop()


def _clip_unit(x: FloatArray) -> FloatArray:
    return np.clip(x, -1.0, 1.0)


class BatchModel:
    """Per run, a model's M(q), C(q, q') q', G(q), F(q'): the controllers' nominal ones, or the true plants'.

    Args:
        params: One parameter set per run.
    """

    def __init__(self, params: Sequence[SMMParameters]) -> None:
        self.inertias = tuple(
            np.array([getattr(p, name) for p in params]) for name in ("I11", "I22", "I44", "I55")
        )
        self.gravity = np.array([-p.gravity_sign * p.mass_lever * p.gravity for p in params])
        self.viscous = pairs(params, lambda p: p.viscous_friction)
        self.coulomb = pairs(params, lambda p: p.coulomb_friction)
        self.offset = pairs(params, lambda p: p.torque_offset)
        self.signed = np.any((self.coulomb != 0.0) | (self.offset != 0.0), axis=1, keepdims=True)

    def friction(self, qd: FloatArray) -> FloatArray:
        """F(q') = f_v q' + f_c sign(q') + offset (N m), (N, 2), as ``smm_dynamics.friction_floats``."""
        viscous = self.viscous * qd
        return np.where(self.signed, viscous + self.coulomb * np.sign(qd) + self.offset, viscous)

    def mass(self, alpha: FloatArray, beta: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(M11, M12, M22) (kg m^2), each (N,)."""
        m11, m12, m22 = mass_matrix_entries_spin_form(
            np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta), *self.inertias
        )
        return m11, m12, m22

    def bias(self, q: FloatArray, qd: FloatArray) -> tuple[FloatArray, ...]:
        """(M11, M12, M22, (C q')_a, (C q')_b, G_a, G_b) at q, q' (N, 2) each; entries (N,)."""
        sb = np.sin(q[:, 1])
        m11, m12, m22, ca, cb = rigid_body_entries_spin_form(
            np.sin(q[:, 0]), np.cos(q[:, 0]), sb, np.cos(q[:, 1]), qd[:, 0], qd[:, 1], *self.inertias
        )
        return m11, m12, m22, ca, cb, np.zeros_like(sb), self.gravity * sb


class BatchTD:
    """``smm_controller.td.TrackingDifferentiator`` per run."""

    def __init__(self, configs: Sequence[TrackingDifferentiatorConfig]) -> None:
        self.sigma = pairs(configs, lambda c: c.speed)
        self.h = pairs(configs, lambda c: c.filter_factor)
        self.x1 = np.zeros_like(self.sigma)
        self.x2 = np.zeros_like(self.sigma)
        self._initialised = False

    def step(self, v: FloatArray, dt: float) -> tuple[FloatArray, FloatArray]:
        """(x1, x2) after one step on the measurement v (N, 2)."""
        if np.any(self.h < dt):
            raise ValueError(f"every filter_factor must be >= dt = {dt!r} s")
        if not self._initialised:
            self.x1 = v.copy()
            self.x2 = np.zeros_like(v)
            self._initialised = True
        sigma, h = self.sigma, self.h
        delta = h * sigma
        delta1 = h * delta
        y = (self.x1 - v) + dt * self.x2
        magnitude = np.abs(y)
        g = np.where(
            magnitude < delta1,
            self.x2 + y / h,
            self.x2 + np.copysign(0.5 * (np.sqrt(8.0 * sigma * magnitude + delta * delta) - delta), y),
        )
        accel = -sigma * np.where(np.abs(g) < delta, g / delta, np.copysign(1.0, g))
        self.x1 = self.x1 + dt * self.x2
        self.x2 = self.x2 + dt * accel
        return self.x1, self.x2


class BatchFLESO:
    """``smm_controller.fleso.FLESO`` per run (all runs share ``grid_points``)."""

    def __init__(self, configs: Sequence[FLESOConfig], model: BatchModel) -> None:
        self.model = model
        self.w0 = pairs(configs, lambda c: c.w0)
        self.k_w = pairs(configs, lambda c: c.k_w)
        self.k_s1 = pairs(configs, lambda c: c.k_s1)
        self.k_s2 = pairs(configs, lambda c: c.k_s2)
        self.w_min = pairs(configs, lambda c: c.w_min)
        self.fuzzy = BandwidthFuzzy(_same(configs, lambda c: c.grid_points, "fleso grid_points"))
        self.compensate = np.array([[c.compensate_friction] for c in configs])
        self.x1 = np.zeros_like(self.w0)
        self.x2 = np.zeros_like(self.w0)
        self.x3 = np.zeros_like(self.w0)
        self.error = np.zeros_like(self.w0)
        self._initialised = False

    def step(self, y: FloatArray, tau: FloatArray, dt: float) -> FloatArray:
        """Disturbance estimate xi~ (N m), (N, 2), for the TD position y and the applied torque tau."""
        if not self._initialised:
            self.x1 = y.copy()
            self._initialised = True
            return np.zeros_like(y)
        m11, m12, m22, c0, c1, g0, g1 = self.model.bias(self.x1, self.x2)
        r0 = tau[:, 0] - c0 - g0
        r1 = tau[:, 1] - c1 - g1
        if self.compensate.any():
            friction = np.where(self.compensate, self.model.friction(self.x2), 0.0)
            r0, r1 = r0 - friction[:, 0], r1 - friction[:, 1]
        det = m11 * m22 - m12 * m12
        acc = np.stack(((m22 * r0 - m12 * r1) / det, (m11 * r1 - m12 * r0) / det), axis=-1)
        p1 = self.x1 + dt * self.x2
        p2 = self.x2 + dt * (self.x3 + acc)
        e = y - p1
        rate = (e - self.error) / dt
        self.error = e
        s = _clip_unit(self.k_s1 * e + self.k_s2 * rate)
        w = np.maximum(self.w0 + self.k_w * self.fuzzy.evaluate(s), self.w_min)
        self.x1 = p1 + dt * (3.0 * w) * e
        self.x2 = p2 + dt * (3.0 * w * w) * e
        self.x3 = self.x3 + dt * (w * w * w) * e
        n11, n12, n22 = self.model.mass(y[:, 0], y[:, 1])
        x3 = self.x3
        return np.stack((-(n11 * x3[:, 0] + n12 * x3[:, 1]), -(n12 * x3[:, 0] + n22 * x3[:, 1])), axis=-1)


class BatchSchedule:
    """``smm_controller.fuzzy_pd.FuzzyPDGainSchedule`` per run."""

    def __init__(self, configs: Sequence[FuzzyPDConfig]) -> None:
        self.k_e = pairs(configs, lambda c: c.k_e)
        self.k_de = pairs(configs, lambda c: c.k_de)
        self.k1 = pairs(configs, lambda c: c.k1)
        self.k2 = pairs(configs, lambda c: c.k2)
        self.kp0 = pairs(configs, lambda c: c.kp0)
        self.kd0 = pairs(configs, lambda c: c.kd0)
        self.fuzzy = PDGainFuzzy(_same(configs, lambda c: c.grid_points, "fuzzy grid_points"))

    def gains(self, e: FloatArray, ed: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(k_p, k_d), (N, 2) each."""
        f_ke, f_kde = self.fuzzy.evaluate(_clip_unit(self.k_e * e), _clip_unit(self.k_de * ed))
        return self.kp0 + self.k1 * f_ke, self.kd0 + self.k2 * f_kde


class BatchLaw:
    """A torque law per run: ``step(reference, q, q', xi~, dt) -> tau`` (N, 2)."""

    uses_observer = np.zeros(0, dtype=bool)
    """Per run: the law takes the FLESO's velocity estimate (FPDESO, velocity_source "observer")."""

    def step(
        self, reference: Reference, q: FloatArray, qd: FloatArray, xi: FloatArray, dt: float
    ) -> FloatArray:
        """The law's torque (N m), (N, 2)."""
        raise NotImplementedError

    def track_saturation(self, unlimited: FloatArray, limited: FloatArray, dt: float) -> None:
        """Anti-windup after the output limits (only the PID has an integrator)."""


class BatchFPDESO(BatchLaw):
    """``smm_controller.fpdeso.FPDESOController`` per run."""

    def __init__(self, configs: Sequence[FPDESOConfig], model: BatchModel) -> None:
        self.model = model
        self.schedule = BatchSchedule([c.fuzzy for c in configs])
        self.b_d = pairs(configs, lambda c: c.robust_gain)
        self.phi = pairs(configs, lambda c: c.boundary_layer)
        self.uses_observer = np.array([c.velocity_source == "observer" for c in configs])
        self.compensate = np.array([[c.compensate_friction] for c in configs])

    def step(
        self, reference: Reference, q: FloatArray, qd: FloatArray, xi: FloatArray, dt: float
    ) -> FloatArray:
        position, velocity, acceleration = reference
        e = position - q
        ed = velocity - qd
        kp, kd = self.schedule.gains(e, ed)
        u = kp * e + kd * ed
        m11, m12, m22, c0, c1, g0, g1 = self.model.bias(q, qd)
        a0, a1 = acceleration[:, 0], acceleration[:, 1]
        u0, u1, ed0, ed1 = u[:, 0], u[:, 1], ed[:, 0], ed[:, 1]
        ff = np.stack((m11 * a0 + m12 * a1 + c0 + g0, m12 * a0 + m22 * a1 + c1 + g1), axis=-1)
        if self.compensate.any():
            ff = np.where(self.compensate, ff + self.model.friction(qd), ff)
        fb = np.stack((m11 * u0 + m12 * u1, m12 * u0 + m22 * u1), axis=-1)
        det = m11 * m22 - m12 * m12
        z = np.stack(((m22 * ed0 - m12 * ed1) / det, (m11 * ed1 - m12 * ed0) / det), axis=-1)
        smooth = self.phi > 0.0
        switch = np.where(smooth, np.clip(z / np.where(smooth, self.phi, 1.0), -1.0, 1.0), np.sign(z))
        v = -self.b_d * switch
        tau: FloatArray = ff + fb + xi - v
        return tau


class BatchFPD(BatchLaw):
    """``smm_controller.baselines.FPDController`` per run."""

    def __init__(self, configs: Sequence[FPDConfig], _model: BatchModel | None = None) -> None:
        self.schedule = BatchSchedule([c.fuzzy for c in configs])
        self.uses_observer = np.zeros(len(configs), dtype=bool)

    def step(
        self, reference: Reference, q: FloatArray, qd: FloatArray, xi: FloatArray, dt: float
    ) -> FloatArray:
        e = reference[0] - q
        ed = reference[1] - qd
        kp, kd = self.schedule.gains(e, ed)
        tau: FloatArray = kp * e + kd * ed
        return tau


def _npd_gain(
    x: FloatArray, coefficient: FloatArray, threshold: FloatArray, exponent: FloatArray
) -> FloatArray:
    magnitude = np.abs(x)
    gain: FloatArray = np.where(
        magnitude > threshold,
        coefficient * np.power(magnitude, exponent - 1.0),
        coefficient * np.power(threshold, exponent - 1.0),
    )
    return gain


class BatchNPD(BatchLaw):
    """``smm_controller.baselines.NPDController`` per run."""

    def __init__(self, configs: Sequence[NPDConfig], _model: BatchModel | None = None) -> None:
        self.k_np, self.k_nd, self.delta_p, self.delta_d, self.rho_p, self.rho_d = _fields(
            configs, ("k_np", "k_nd", "delta_p", "delta_d", "rho_p", "rho_d")
        )
        self.uses_observer = np.zeros(len(configs), dtype=bool)

    def step(
        self, reference: Reference, q: FloatArray, qd: FloatArray, xi: FloatArray, dt: float
    ) -> FloatArray:
        e = reference[0] - q
        ed = reference[1] - qd
        kp = _npd_gain(e, self.k_np, self.delta_p, self.rho_p)
        kd = _npd_gain(ed, self.k_nd, self.delta_d, self.rho_d)
        tau: FloatArray = kp * e + kd * ed
        return tau


class BatchPID(BatchLaw):
    """``smm_controller.baselines.PIDController`` per run."""

    def __init__(self, configs: Sequence[PIDConfig], _model: BatchModel | None = None) -> None:
        self.kp, self.ki, self.kd, self.n, self.i_max, self.limit = _fields(
            configs, ("kp", "ki", "kd", "derivative_filter", "integrator_limit", "output_limit")
        )
        self.integral = np.zeros_like(self.kp)
        self.derivative = np.zeros_like(self.kp)
        self.previous: FloatArray | None = None
        self.uses_observer = np.zeros(len(configs), dtype=bool)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            tracking = np.where(self.kd > 0.0, np.sqrt(self.kd / self.ki), self.kp / self.ki)
        self._tracks = (self.ki > 0.0) & (tracking > 0.0)
        self._tracking_time = np.where(self._tracks, tracking, 1.0)

    def step(
        self, reference: Reference, q: FloatArray, qd: FloatArray, xi: FloatArray, dt: float
    ) -> FloatArray:
        e = reference[0] - q
        previous = self.previous if self.previous is not None else e
        self.derivative = (self.derivative + self.kd * self.n * (e - previous)) / (1.0 + self.n * dt)
        p = self.kp * e
        held = self.integral
        integral = np.clip(held + self.ki * e * dt, -self.i_max, self.i_max)
        unclamped = p + integral + self.derivative
        hold = (np.abs(unclamped) > self.limit) & (e * unclamped > 0.0)
        integral = np.where(hold, held, integral)
        unclamped = np.where(hold, p + integral + self.derivative, unclamped)
        self.integral = integral
        self.previous = e
        tau: FloatArray = np.clip(unclamped, -self.limit, self.limit)
        return tau

    def track_saturation(self, unlimited: FloatArray, limited: FloatArray, dt: float) -> None:
        corrected = np.clip(
            self.integral + dt * (limited - unlimited) / self._tracking_time, -self.i_max, self.i_max
        )
        self.integral = np.where(self._tracks, corrected, self.integral)


class BatchLimiter:
    """``smm_controller.limits.OutputLimiter`` per run: rate limit, then magnitude limit."""

    def __init__(self, configs: Sequence[OutputLimitConfig]) -> None:
        self.bound = pairs(configs, lambda c: c.torque_limit)
        self.rate = pairs(configs, lambda c: c.rate_limit)
        self.previous: FloatArray | None = None

    def limit(self, tau: FloatArray, dt: float) -> FloatArray:
        """The limited command (N m), (N, 2); a non-finite torque passes unchanged (as the scalar)."""
        finite = np.isfinite(tau)
        value = tau
        if self.previous is not None:
            step = self.rate * dt
            value = np.where(finite, np.clip(value, self.previous - step, self.previous + step), value)
        result = np.where(finite, np.clip(value, -self.bound, self.bound), value)
        self.previous = result
        return result


def make_batch_law(name: str, configs: Sequence[Any], model: BatchModel) -> BatchLaw:
    """The batched twin of law ``name`` (``smm_controller.laws``) with one config per run.

    Raises:
        UnknownLawError: No law has this name, or it has no batched twin.
    """
    law: BatchLaw = batched_twin(get_law(name))(configs, model)
    return law


class BatchChain:
    """``smm_controller.chain.ControlChain`` per run: TD -> FLESO (FPDESO) -> law -> limits."""

    def __init__(self, td: BatchTD, fleso: BatchFLESO | None, law: BatchLaw, limiter: BatchLimiter) -> None:
        if fleso is None and np.any(law.uses_observer):
            raise ValueError("a law's velocity_source is 'observer' but the chain has no FLESO")
        self.td, self.fleso, self.law, self.limiter = td, fleso, law, limiter

    def step(self, y: FloatArray, tau_applied: FloatArray, reference: Reference, dt: float) -> FloatArray:
        """The limited torque command (N m), (N, 2)."""
        q, qd = self.td.step(y, dt)
        if self.fleso is not None:
            xi = self.fleso.step(q, tau_applied, dt)
            qd = np.where(self.law.uses_observer[:, None], self.fleso.x2, qd)
        else:
            xi = np.zeros_like(q)
        tau = self.law.step(reference, q, qd, xi, dt)
        limited = self.limiter.limit(tau, dt)
        changed = np.any(limited != tau, axis=1) & np.all(np.isfinite(tau) & np.isfinite(limited), axis=1)
        if np.any(changed):
            corrected = np.where(changed[:, None], limited, tau)
            self.law.track_saturation(tau, corrected, dt)
        return limited
