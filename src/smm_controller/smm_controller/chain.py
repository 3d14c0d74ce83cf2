"""The control chain TD -> FLESO -> law -> output limits, one step per call, and the paper's factories.

:meth:`ControlChain.step`: y_k (rad, (2,)), tau_applied_{k-1} (N m, (2,)), r_k ((3, 2)) -> tau_k (N m, (2,));
every stage runs on plain floats (``step_floats``). Order, velocity source and limits: docs/DESIGN.md,
"The control chain and its order".
"""

from __future__ import annotations

import types
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from smm_controller._validation import FloatArray, as_joint_vector, as_reference, check_dt
from smm_controller.fleso import FLESO, FLESOConfig
from smm_controller.laws import get_law, law_for_config
from smm_controller.limits import OutputLimitConfig, OutputLimiter, track_saturation
from smm_controller.td import TrackingDifferentiator, TrackingDifferentiatorConfig
from smm_controller.torque_law import TorqueLaw
from smm_dynamics import SMMParameters

__all__ = [
    "ControlChain",
    "JointController",
    "build_chain",
    "limited_torque",
    "make_chain",
    "make_controller",
    "make_law",
    "stage_internals",
]


JointController = TorqueLaw
"""The interface shared by FPDESO and the baselines (see :class:`smm_controller.torque_law.TorqueLaw`)."""


def make_law(config: object, params: SMMParameters) -> JointController:
    """The law ``config`` configures (its type says which, :func:`~smm_controller.laws.law_for_config`).

    Args:
        config: A law's config.
        params: The nominal model (for the laws that use it).

    Raises:
        UnknownLawError: ``config`` is the config of no law.
    """
    law: JointController = law_for_config(config).build(config, params)
    return law


def stage_internals(stage: str, internals: Mapping[str, FloatArray]) -> dict[str, FloatArray]:
    """A stage's internals under the chain's labels: ``"<stage>.<key>"`` (``"controller.kp"``, ...).

    One labelling for the offline loop and every node layout, so a row means the same in every bag.
    """
    return {f"{stage}.{key}": value for key, value in internals.items()}


def limited_torque(
    controller: TorqueLaw,
    limiter: OutputLimiter,
    reference: Sequence[Sequence[float]],
    q: tuple[float, float],
    q_dot: tuple[float, float],
    *,
    disturbance: tuple[float, float],
    dt: float,
) -> tuple[float, float]:
    """Step 4 of the chain: the law's torque (N m) through the output limits, the law told what was cut."""
    tau = controller.step_floats(reference, q, q_dot, disturbance, dt)
    limited = limiter.limit_floats(tau, dt)
    track_saturation(controller, tau, limited, dt)
    return limited


class ControlChain:
    """TD -> FLESO -> controller, one control step per call.

    Args:
        td: Tracking differentiator applied to the measured position.
        fleso: Disturbance observer, or None (xi~ = 0, as for the baselines).
        controller: FPDESO or a baseline.
        limiter: Output limits applied after the controller (default: :class:`OutputLimiter` with its
            default torque limit).
    """

    def __init__(
        self,
        td: TrackingDifferentiator,
        fleso: FLESO | None,
        controller: JointController,
        limiter: OutputLimiter | None = None,
    ) -> None:
        if fleso is None and controller.velocity_source == "observer":
            raise ValueError("the law's velocity_source is 'observer' but the chain has no FLESO")
        self.td = td
        self.fleso = fleso
        self.controller = controller
        self.limiter = limiter if limiter is not None else OutputLimiter()
        self._disturbance = (0.0, 0.0)

    def reset(self) -> None:
        """Resets every stage."""
        self.td.reset()
        if self.fleso is not None:
            self.fleso.reset()
        self.controller.reset()
        self.limiter.reset()
        self._disturbance = (0.0, 0.0)

    def prepare(self, dt: float) -> None:
        """Does ahead what the next step (of length ``dt``, s) needs no measurement for; optional.

        The FLESO's model terms at its estimate and at the TD's next position.
        """
        if self.fleso is not None:
            self.fleso.prepare(self.td.next_position(dt))

    def step(
        self, y: npt.ArrayLike, tau_applied: npt.ArrayLike, reference: npt.ArrayLike, dt: float
    ) -> FloatArray:
        """One control step.

        Args:
            y: Measured position (rad), shape (2,).
            tau_applied: Torque applied during the previous interval (N m), shape (2,).
            reference: Rows q_d (rad), q_d' (rad/s), q_d'' (rad/s^2); columns alpha, beta;
                shape (3, 2).
            dt: Control period (s), > 0.

        Returns:
            Torque command tau (N m), shape (2,).
        """
        check_dt(dt)
        return np.array(
            self.step_floats(
                as_joint_vector("y", y),
                as_joint_vector("tau_applied", tau_applied),
                as_reference(reference).tolist(),
                dt,
            )
        )

    def advance_estimators(
        self, y: tuple[float, float], tau_applied: tuple[float, float], dt: float, steps: int
    ) -> None:
        """TD and FLESO ``steps`` steps of ``dt`` (s) towards y (rad), no law: missed control periods.

        Their inputs are y interpolated linearly from the TD's last input (rad) and tau_applied (N m)
        held; the step on y follows (docs/DESIGN.md, "Missed control periods").
        """
        td, fleso = self.td, self.fleso
        if td.next_position(dt) is None:
            return  # no step yet: nothing to catch up from
        start0, start1 = (float(v) for v in td.internals["input"])
        rise0, rise1 = y[0] - start0, y[1] - start1
        for i in range(1, steps + 1):
            share = i / (steps + 1)
            q0, q1, _qd0, _qd1 = td.step_floats(start0 + share * rise0, start1 + share * rise1, dt)
            if fleso is not None:
                fleso.step_floats(q0, q1, tau_applied[0], tau_applied[1], dt)

    def step_floats(
        self,
        y: tuple[float, float],
        tau_applied: tuple[float, float],
        reference: Sequence[Sequence[float]],
        dt: float,
    ) -> tuple[float, float]:
        """Same as :meth:`step` on floats (reference as nested 3x2 lists); returns (tau_a, tau_b)."""
        q0, q1, qd0, qd1 = self.td.step_floats(y[0], y[1], dt)
        if self.fleso is not None:
            disturbance = self.fleso.step_floats(q0, q1, tau_applied[0], tau_applied[1], dt)
            if self.controller.velocity_source == "observer":
                qd0, qd1 = self.fleso.velocity_floats()
        else:
            disturbance = (0.0, 0.0)
            if self.controller.velocity_source == "observer":
                raise ValueError("the law's velocity_source is 'observer' but the chain has no FLESO")
        self._disturbance = disturbance
        return limited_torque(
            self.controller, self.limiter, reference, (q0, q1), (qd0, qd1), disturbance=disturbance, dt=dt
        )

    @property
    def disturbance_estimate(self) -> tuple[float, float]:
        """The last step's disturbance estimate (N m; zeros without FLESO), as ``internals`` has it."""
        return self._disturbance

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Every stage's internals, keys prefixed ``td.``, ``fleso.``, ``controller.``, ``limiter.``; (2,)."""
        merged = stage_internals("td", self.td.internals)
        if self.fleso is not None:
            merged.update(stage_internals("fleso", self.fleso.internals))
        merged.update(stage_internals("controller", self.controller.internals))
        merged.update(stage_internals("limiter", self.limiter.internals))
        disturbance = np.array(self._disturbance)
        disturbance.flags.writeable = False
        merged["disturbance_estimate"] = disturbance
        return types.MappingProxyType(merged)


def make_controller(name: str, params: SMMParameters) -> JointController:
    """Law ``name`` of :func:`~smm_controller.laws.law_table` with its default gains.

    Raises:
        UnknownLawError: No law has this name.
    """
    law = get_law(name)
    built: JointController = law.build(law.config(), params)
    return built


def build_chain(
    name: str,
    model: SMMParameters,
    *,
    law: JointController | None = None,
    td: TrackingDifferentiatorConfig | None = None,
    fleso: FLESOConfig | None = None,
    limiter: OutputLimiter | OutputLimitConfig | None = None,
) -> ControlChain:
    """The chain of law ``name``: TD -> FLESO (when the law uses the disturbance estimate) -> law -> limits.

    The one place the chain is assembled (node, offline loop, rerun).

    Args:
        name: A law of :func:`~smm_controller.laws.law_table`.
        model: Nominal model parameters (FLESO, and the laws that use a model).
        law: The running law to put in the chain (default: law ``name`` with its default gains).
        td: TD parameters (default: its defaults).
        fleso: FLESO parameters (default: the paper's); unused without the FLESO.
        limiter: The output limiter to share, or its config (default: ``OutputLimitConfig()``).

    Raises:
        UnknownLawError: No law has this name.
    """
    row = get_law(name)
    controller = law if law is not None else make_controller(name, model)
    observer = FLESO(fleso, model) if row.uses_disturbance_estimate else None
    limits = limiter if isinstance(limiter, OutputLimiter) else OutputLimiter(limiter)
    return ControlChain(TrackingDifferentiator(td), observer, controller, limits)


def make_chain(name: str, params: SMMParameters) -> ControlChain:
    """The full chain of law ``name`` with default gains (:func:`build_chain`)."""
    return build_chain(name, params)
