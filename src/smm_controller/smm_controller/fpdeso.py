"""FPDESO control law (paper eq. 26-30; SPEC section 4): tau = M(q)(q_d'' + u) + C(q, q') q' + G(q) + xi~ - v.

u = k_p e + k_d e' (rad/s^2, fuzzy-scheduled gains), v = -b_d sign(M^-1(q) e') (N m); per joint, shape (2,).
The split into feedforward, feedback and compensation, the boundary layer, ``compensate_friction`` and
``velocity_source``: docs/DESIGN.md, "FPDESO".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from smm_schema.ranges import at_least, check_bounds

from smm_controller._validation import (
    FloatArray,
    check_instance,
    internals_view,
)
from smm_controller.fuzzy_pd import PAPER_FPDESO_FUZZY, FuzzyPDConfig, FuzzyPDGainSchedule
from smm_controller.model import NominalModel
from smm_controller.torque_law import TorqueLaw
from smm_dynamics import SMMParameters

__all__ = ["VELOCITY_SOURCES", "FPDESOConfig", "FPDESOController", "robust_switch"]

#: Values of :attr:`FPDESOConfig.velocity_source`.
VELOCITY_SOURCES: tuple[str, str] = ("td", "observer")


@dataclass(frozen=True)
class FPDESOConfig:
    """FPDESO parameters per joint (alpha, beta); defaults are the paper's (Section V.A).

    Attributes:
        fuzzy: Fuzzy PD gain schedule (gains in 1/s^2 and 1/s).
        robust_gain: b_d, bound of the disturbance estimation error (N m), >= 0.
        boundary_layer: phi, width of the boundary layer of the robust term, >= 0 (0 = pure sign).
        velocity_source: q' of the law: "td" (paper, eq. 26: the TD's x2) or "observer" (the FLESO's x2^).
        compensate_friction: Add the model's friction F(q') to the feedforward (False: the paper's law).
    """

    fuzzy: FuzzyPDConfig = PAPER_FPDESO_FUZZY
    robust_gain: tuple[float, float] = field(default=(0.03 * math.pi, 0.02 * math.pi), metadata=at_least(0.0))
    boundary_layer: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    velocity_source: str = "observer"
    compensate_friction: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.fuzzy, FuzzyPDConfig):
            raise ValueError(f"fuzzy must be a FuzzyPDConfig, got {self.fuzzy!r}")
        check_bounds(self)
        if self.velocity_source not in VELOCITY_SOURCES:
            raise ValueError(
                f"velocity_source must be one of {VELOCITY_SOURCES}, got {self.velocity_source!r}"
            )
        if not isinstance(self.compensate_friction, bool):
            raise ValueError(f"compensate_friction must be a bool, got {self.compensate_friction!r}")


def robust_switch(x: float, phi: float) -> float:
    """sign(x) for phi = 0 (with sign(0) = 0), else the saturation sat(x / phi) in [-1, 1]."""
    if phi > 0.0:
        ratio = x / phi
        return -1.0 if ratio < -1.0 else (1.0 if ratio > 1.0 else ratio)
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


class FPDESOController(TorqueLaw):
    """Fuzzy PD inverse-dynamics decoupling law with disturbance compensation and robust term.

    Args:
        config: Gains (default: the paper's).
        params: The controller's nominal model parameters (not the plant's).
    """

    def __init__(self, config: FPDESOConfig | None, params: SMMParameters) -> None:
        self.config = config if config is not None else FPDESOConfig()
        self.model = NominalModel.shared(params)
        self.schedule = FuzzyPDGainSchedule(self.config.fuzzy)
        self.reset()

    @property
    def velocity_source(self) -> str:
        """Which velocity estimate the chain gives this law: "td" or "observer"."""
        return self.config.velocity_source

    def reset(self) -> None:
        """The law is memoryless; this clears the recorded internals."""
        self.schedule.reset()
        self._last: tuple[float, ...] = (0.0,) * 16

    def reconfigure(self, config: FPDESOConfig, *, params: SMMParameters | None = None) -> None:
        """Takes new gains (and optionally a new nominal model) for the next step.

        The law is memoryless, so the next torque is that of a new controller with the same config;
        the recorded internals are kept until then.

        Args:
            config: The new gains (replaces the config whole).
            params: The new nominal model parameters; None keeps the current model.

        Raises:
            TypeError: ``config`` is not an :class:`FPDESOConfig` or ``params`` not an ``SMMParameters``.
        """
        check_instance("config", config, FPDESOConfig)
        if params is not None:
            self.model = NominalModel.shared(check_instance("params", params, SMMParameters))
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
        (position0, position1), (velocity0, velocity1), (acceleration0, acceleration1) = reference
        q0, q1 = q
        qd0, qd1 = q_dot
        xi0, xi1 = disturbance_estimate
        e0 = position0 - q0
        e1 = position1 - q1
        ed0 = velocity0 - qd0
        ed1 = velocity1 - qd1
        kp0, kp1, kd0, kd1 = self.schedule.step_floats(e0, e1, ed0, ed1)
        u0 = kp0 * e0 + kd0 * ed0
        u1 = kp1 * e1 + kd1 * ed1
        model = self.model
        m11, m12, m22, c0, c1, g0, g1 = model.bias(q0, q1, qd0, qd1)
        ff0 = m11 * acceleration0 + m12 * acceleration1 + c0 + g0
        ff1 = m12 * acceleration0 + m22 * acceleration1 + c1 + g1
        config = self.config
        if config.compensate_friction:
            friction0, friction1 = model.friction(qd0, qd1)
            ff0 += friction0
            ff1 += friction1
        fb0 = m11 * u0 + m12 * u1
        fb1 = m12 * u0 + m22 * u1
        # sign(M^-1 e') = sign(adj(M) e') since det M > 0.
        z0 = m22 * ed0 - m12 * ed1
        z1 = m11 * ed1 - m12 * ed0
        det = m11 * m22 - m12 * m12
        (b_d0, b_d1), (phi0, phi1) = config.robust_gain, config.boundary_layer
        v0 = -b_d0 * robust_switch(z0 / det, phi0)
        v1 = -b_d1 * robust_switch(z1 / det, phi1)
        tau0 = ff0 + fb0 + xi0 - v0
        tau1 = ff1 + fb1 + xi1 - v1
        self._last = (kp0, kp1, kd0, kd1, u0, u1, ff0, ff1, fb0, fb1, xi0, xi1, v0, v1, tau0, tau1)
        return tau0, tau1

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only copies, shape (2,), of the terms of the last step.

        Keys: kp, kd, u (rad/s^2), feedforward (tau_c1, with F(q') if compensated), feedback (M u),
        disturbance (xi~), robust (v), tau; torques in N m,
        tau = feedforward + feedback + disturbance - robust.
        """
        return internals_view(
            ("kp", "kd", "u", "feedforward", "feedback", "disturbance", "robust", "tau"), self._last
        )
