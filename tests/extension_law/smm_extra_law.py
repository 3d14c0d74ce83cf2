"""A fifth control law in its own module, registered only through the ``smm_controller.laws`` entry point.

A plain linear PD, tau = k_p e + k_d e' per joint; the acceptance tests install it into a temporary folder
(a ``.dist-info`` with the entry point) and check that every part of the stack accepts it unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from smm_controller.laws import Law
from smm_controller.torque_law import TorqueLaw
from smm_schema.ranges import above, check_bounds

from smm_dynamics import SMMParameters

NAME = "linpd"


@dataclass(frozen=True)
class LinearPDConfig:
    """Gains of the linear PD.

    Attributes:
        kp: Proportional gain per joint (N m/rad), > 0.
        kd: Derivative gain per joint (N m s/rad), > 0.
    """

    kp: tuple[float, float] = field(default=(900.0, 900.0), metadata=above(0.0))
    kd: tuple[float, float] = field(default=(60.0, 60.0), metadata=above(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)


class LinearPD(TorqueLaw):
    """tau = k_p e + k_d e' (N m), memoryless."""

    def __init__(self, config: LinearPDConfig) -> None:
        self.config = config
        self._tau = (0.0, 0.0)

    def reconfigure(self, config: LinearPDConfig) -> None:
        """New gains for the next step."""
        self.config = config

    def step_floats(
        self,
        reference: Sequence[Sequence[float]],
        q: tuple[float, float],
        q_dot: tuple[float, float],
        disturbance_estimate: tuple[float, float],
        dt: float,
    ) -> tuple[float, float]:
        """The torque (N m) on floats."""
        kp, kd = self.config.kp, self.config.kd
        self._tau = (
            kp[0] * (reference[0][0] - q[0]) + kd[0] * (reference[1][0] - q_dot[0]),
            kp[1] * (reference[0][1] - q[1]) + kd[1] * (reference[1][1] - q_dot[1]),
        )
        return self._tau

    def reset(self) -> None:
        """Forgets the last torque."""
        self._tau = (0.0, 0.0)

    @property
    def internals(self) -> Mapping[str, np.ndarray]:
        """The last torque, (2,)."""
        tau = np.array(self._tau)
        tau.flags.writeable = False
        return {"tau": tau}


def _build(config: LinearPDConfig, _model: SMMParameters) -> LinearPD:
    return LinearPD(config)


def _reconfigure(law: LinearPD, config: LinearPDConfig, _model: SMMParameters) -> None:
    law.reconfigure(config)


LAW: Law[LinearPDConfig, LinearPD] = Law(
    NAME,
    LinearPDConfig,
    _build,
    _reconfigure,
    batched="smm_extra_law_batch:BatchLinearPD",
    label="linear PD",
)
"""The row the entry point names."""
