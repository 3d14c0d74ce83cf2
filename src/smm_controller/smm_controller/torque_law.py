"""The interface every joint torque law shares (FPDESO and the baselines).

Each law implements ``step_floats`` on plain floats (the 1 kHz hot path), ``reset`` and ``internals``; this
base class validates and converts the array arguments of ``step`` once, so no law repeats that code, and is
the type the chain, the offline loop and the controller node accept.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from smm_controller._validation import FloatArray, as_joint_vector, as_reference, check_dt


class TorqueLaw:
    """Array interface of a joint torque law: validation and conversion around ``step_floats``."""

    @property
    def velocity_source(self) -> str:
        """Which velocity estimate the chain gives this law: "td" (the baselines) or "observer"."""
        return "td"

    def step(
        self,
        reference: npt.ArrayLike,
        q: npt.ArrayLike,
        q_dot: npt.ArrayLike,
        disturbance_estimate: npt.ArrayLike,
        dt: float,
    ) -> FloatArray:
        """Joint torque command.

        Args:
            reference: Rows q_d (rad), q_d' (rad/s), q_d'' (rad/s^2); columns alpha, beta; shape (3, 2).
            q: Position estimate (rad), shape (2,).
            q_dot: Velocity estimate (rad/s), shape (2,).
            disturbance_estimate: xi~ (N m), shape (2,); used by FPDESO, ignored by the baselines.
            dt: Control period (s), > 0.

        Returns:
            tau (N m), shape (2,).
        """
        check_dt(dt)
        ref = as_reference(reference).tolist()
        return np.array(
            self.step_floats(
                ref,
                as_joint_vector("q", q),
                as_joint_vector("q_dot", q_dot),
                as_joint_vector("disturbance_estimate", disturbance_estimate),
                dt,
            )
        )

    def step_floats(
        self,
        reference: Sequence[Sequence[float]],
        q: tuple[float, float],
        q_dot: tuple[float, float],
        disturbance_estimate: tuple[float, float],
        dt: float,
    ) -> tuple[float, float]:
        """Same as :meth:`step` on floats (reference as nested 3x2 lists); returns (tau_a, tau_b)."""
        raise NotImplementedError

    def reset(self) -> None:
        """Restores the initial state."""
        raise NotImplementedError

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only copies of the internal signals, each shape (2,)."""
        raise NotImplementedError
