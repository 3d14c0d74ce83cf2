"""Fuzzy linear extended state observer (FLESO, paper eq. 19-23 with fuzzy bandwidth; SPEC section 4).

Per joint: states x1^ (rad), x2^ (rad/s), x3^ (rad/s^2) from the TD position y (rad) and the applied torque
tau (N m); total disturbance estimate xi~ = -M(y) x3^ (N m, shape (2,)). Equations, discretisation, fuzzy
input and initialisation: docs/DESIGN.md, "FLESO".
"""

from __future__ import annotations

import types
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from smm_schema.ranges import above, at_least, check_bounds

from smm_controller._validation import (
    FloatArray,
    as_joint_vector,
    check_dt,
    check_instance,
    readonly_copies,
)
from smm_controller.fuzzy_batch import MamdaniBatch
from smm_controller.model import NominalModel
from smm_controller.rules import fleso_bandwidth_system
from smm_dynamics import SMMParameters

__all__ = ["DEFAULT_FLESO_W_MIN", "FLESO", "FLESOConfig", "observer_gains"]

#: Floor of the observer bandwidth per joint (rad/s). The paper's gains keep w >= w0 - k_w
#: (9 and 8 rad/s), so the floor only matters for retuned gains with k_w >= w0.
DEFAULT_FLESO_W_MIN: tuple[float, float] = (1.0, 1.0)


@dataclass(frozen=True)
class FLESOConfig:
    """FLESO parameters per joint (alpha, beta); defaults are the paper's (Section V.A).

    Attributes:
        w0: Nominal observer bandwidth (rad/s), > 0.
        k_w: Scale of the fuzzy bandwidth correction f(w) in [-1, 1] (rad/s), >= 0.
        k_s1: Weight of the estimation error E in the fuzzy input (1/rad), >= 0.
        k_s2: Weight of its rate E' in the fuzzy input (s/rad), >= 0.
        w_min: Floor of the bandwidth (rad/s), > 0.
        grid_points: Defuzzification grid size over [-1, 1], integer >= 3.
        compensate_friction: The observer's model holds the model's friction F(x2^), so xi~ leaves it
            out; set it with FPDESO's ``compensate_friction`` (False: the paper's observer).
    """

    w0: tuple[float, float] = field(default=(20.0, 28.0), metadata=above(0.0))
    k_w: tuple[float, float] = field(default=(11.0, 20.0), metadata=at_least(0.0))
    k_s1: tuple[float, float] = field(default=(3.0, 5.0), metadata=at_least(0.0))
    k_s2: tuple[float, float] = field(default=(1.15, 0.98), metadata=at_least(0.0))
    w_min: tuple[float, float] = field(default=DEFAULT_FLESO_W_MIN, metadata=above(0.0))
    grid_points: int = field(default=201, metadata=at_least(3))
    compensate_friction: bool = False

    def __post_init__(self) -> None:
        check_bounds(self)
        if not isinstance(self.compensate_friction, bool):
            raise ValueError(f"compensate_friction must be a bool, got {self.compensate_friction!r}")


def _clip_unit(x: float) -> float:
    return -1.0 if x < -1.0 else (1.0 if x > 1.0 else x)


def _bandwidth_batch(grid_points: int) -> MamdaniBatch:
    """The bandwidth rule base of both joints, defuzzified on ``grid_points`` points."""
    system = fleso_bandwidth_system(grid_points)
    return MamdaniBatch([system, system])


def observer_gains(bandwidth: float) -> tuple[float, float, float]:
    """LESO gains (l1, l2, l3) = (3 w, 3 w^2, w^3) placing all error poles at -w (eq. 22-23).

    Args:
        bandwidth: w (rad/s), > 0.

    Returns:
        (l1 in 1/s, l2 in 1/s^2, l3 in 1/s^3).
    """
    return 3.0 * bandwidth, 3.0 * bandwidth * bandwidth, bandwidth * bandwidth * bandwidth


class FLESO:
    """Fuzzy-bandwidth linear extended state observer for both joints.

    Args:
        config: Observer parameters (default: the paper's).
        params: The controller's nominal model parameters (not the plant's).
    """

    def __init__(self, config: FLESOConfig | None, params: SMMParameters) -> None:
        self.config = config if config is not None else FLESOConfig()
        self.model = NominalModel.shared(params)
        self._batch = _bandwidth_batch(self.config.grid_points)
        self.reset()

    def reset(self) -> None:
        """Forgets the state; the next step re-initialises x1^ = y, x2^ = x3^ = 0."""
        self._initialised = False
        self._x1 = [0.0, 0.0]
        self._x2 = [0.0, 0.0]
        self._x3 = [0.0, 0.0]
        self._error = [0.0, 0.0]
        self._last: tuple[float, ...] = (0.0,) * 10
        self._ahead: tuple[float, float, float, float, float, float, float] | None = None

    def reconfigure(self, config: FLESOConfig, *, params: SMMParameters | None = None) -> None:
        """Takes new gains (and optionally a new nominal model) for the next step and keeps the state.

        Kept: x1^, x2^, x3^ (so the disturbance estimate does not drop to 0) and the previous innovation
        (so E' stays continuous). The fuzzy bandwidth system is rebuilt when ``grid_points`` changes.

        Args:
            config: The new observer parameters (replaces the config whole).
            params: The new nominal model parameters; None keeps the current model.

        Raises:
            TypeError: ``config`` is not a :class:`FLESOConfig` or ``params`` not an ``SMMParameters``.
        """
        check_instance("config", config, FLESOConfig)
        if params is not None:
            self.model = NominalModel.shared(check_instance("params", params, SMMParameters))
            self._ahead = None
        if config.grid_points != self.config.grid_points:
            self._batch = _bandwidth_batch(config.grid_points)
        self.config = config

    def prepare(self, next_y: tuple[float, float] | None = None) -> None:
        """Evaluates the model where the next step will: at the current estimate, and M at ``next_y``.

        ``next_y``: the next step's position when known ahead (the TD's, rad). A loop with idle time after
        its send calls this there; the next step then takes the terms instead of evaluating them (the same
        values, so the same step).
        """
        if self._initialised:
            x1, x2 = self._x1, self._x2
            self._ahead = self.model.bias(x1[0], x1[1], x2[0], x2[1])
        if next_y is not None:
            self.model.mass(next_y[0], next_y[1])  # the model keeps the last M it evaluated

    def step(self, y: npt.ArrayLike, tau_applied: npt.ArrayLike, dt: float) -> FloatArray:
        """Advances the observer to the current sample.

        Args:
            y: TD-filtered position (rad), shape (2,).
            tau_applied: Torque applied since the previous step (N m), shape (2,).
            dt: Time since the previous step (s), > 0.

        Returns:
            Disturbance estimate xi~ = -M(y) x3^ (N m), shape (2,).
        """
        check_dt(dt)
        y0, y1 = as_joint_vector("y", y)
        tau0, tau1 = as_joint_vector("tau_applied", tau_applied)
        return np.array(self.step_floats(y0, y1, tau0, tau1, dt))

    def step_floats(self, y0: float, y1: float, tau0: float, tau1: float, dt: float) -> tuple[float, float]:
        """Same as :meth:`step` on floats: returns (xi~_alpha, xi~_beta) in N m."""
        x1 = self._x1
        x2 = self._x2
        x3 = self._x3
        model = self.model
        config = self.config
        if not self._initialised:
            x1[0] = y0
            x1[1] = y1
            x2[0] = x2[1] = x3[0] = x3[1] = 0.0
            self._error[0] = self._error[1] = 0.0
            self._initialised = True
            w_nominal = config.w0
            self._last = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, w_nominal[0], w_nominal[1], 0.0, 0.0)
            return 0.0, 0.0
        x1a, x1b = x1
        x2a, x2b = x2
        # Prediction to t_k with the model and the torque that acted over [t_{k-1}, t_k].
        ahead, self._ahead = self._ahead, None
        m11, m12, m22, c0, c1, g0, g1 = model.bias(x1a, x1b, x2a, x2b) if ahead is None else ahead
        r0 = tau0 - c0 - g0
        r1 = tau1 - c1 - g1
        if config.compensate_friction:
            friction0, friction1 = model.friction(x2a, x2b)
            r0 -= friction0
            r1 -= friction1
        det = m11 * m22 - m12 * m12
        acc0 = (m22 * r0 - m12 * r1) / det
        acc1 = (m11 * r1 - m12 * r0) / det
        p10 = x1a + dt * x2a
        p11 = x1b + dt * x2b
        p20 = x2a + dt * (x3[0] + acc0)
        p21 = x2b + dt * (x3[1] + acc1)
        # Fuzzy bandwidth from the innovation and its rate.
        e0 = y0 - p10
        e1 = y1 - p11
        error = self._error
        rate0 = (e0 - error[0]) / dt
        rate1 = (e1 - error[1]) / dt
        error[0] = e0
        error[1] = e1
        (k_s1a, k_s1b), (k_s2a, k_s2b) = config.k_s1, config.k_s2
        s0 = _clip_unit(k_s1a * e0 + k_s2a * rate0)
        s1 = _clip_unit(k_s1b * e1 + k_s2b * rate1)
        f0, f1 = self._batch.evaluate_flat(((s0,), (s1,)))
        (w0a, w0b), (k_wa, k_wb), (w_mina, w_minb) = config.w0, config.k_w, config.w_min
        w0 = max(w0a + k_wa * f0, w_mina)
        w1 = max(w0b + k_wb * f1, w_minb)
        l10, l20, l30 = observer_gains(w0)
        l11, l21, l31 = observer_gains(w1)
        x1[0] = p10 + dt * l10 * e0
        x1[1] = p11 + dt * l11 * e1
        x2[0] = p20 + dt * l20 * e0
        x2[1] = p21 + dt * l21 * e1
        x3a = x3[0] = x3[0] + dt * l30 * e0
        x3b = x3[1] = x3[1] + dt * l31 * e1
        n11, n12, n22 = model.mass(y0, y1)
        xi0 = -(n11 * x3a + n12 * x3b)
        xi1 = -(n12 * x3a + n22 * x3b)
        self._last = (e0, e1, rate0, rate1, s0, s1, w0, w1, xi0, xi1)
        return xi0, xi1

    def velocity_floats(self) -> tuple[float, float]:
        """The velocity estimate x2^ after the last step (rad/s), (alpha, beta)."""
        return self._x2[0], self._x2[1]

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only copies, shape (2,).

        Keys: x1_hat (rad), x2_hat (rad/s), x3_hat (rad/s^2), estimation_error E (rad),
        estimation_error_rate E' (rad/s), fuzzy_input s, bandwidth w (rad/s), xi_tilde (N m).
        """
        last = self._last
        return types.MappingProxyType(
            readonly_copies(
                {
                    "x1_hat": self._x1,
                    "x2_hat": self._x2,
                    "x3_hat": self._x3,
                    "estimation_error": last[0:2],
                    "estimation_error_rate": last[2:4],
                    "fuzzy_input": last[4:6],
                    "bandwidth": last[6:8],
                    "xi_tilde": last[8:10],
                }
            )
        )
