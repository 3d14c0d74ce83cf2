"""Open-loop identification data: a prescribed excitation and the exact inverse-dynamics torque."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from smm_controller.excitation import ExcitationReference

from smm_dynamics import SMMParameters, inverse_dynamics

PERIOD_NS = 1_000_000
TRUTH = SMMParameters(
    I11=0.061,
    I22=0.083,
    I44=0.077,
    I55=0.064,
    mass_lever=0.047,
    viscous_friction=(0.21, 0.14),
    coulomb_friction=(0.08, 0.11),
    torque_offset=(-0.04, 0.06),
)


def synthetic_run(
    params: SMMParameters = TRUTH, reference: ExcitationReference | None = None, *, only_beta: bool = False
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """(t_ns, position, effort): positions at the stamps, effort the torque at each interval's midpoint."""
    reference = reference if reference is not None else ExcitationReference()
    steps = round((reference.duration + 0.5) * 1e9 / PERIOD_NS)
    t_ns = np.arange(steps, dtype=np.int64) * PERIOD_NS
    at_stamps = reference.sample(t_ns / 1e9)
    mid = reference.sample((t_ns - PERIOD_NS / 2) / 1e9)
    if only_beta:
        at_stamps[:, :, 0] = 0.0
        mid[:, :, 0] = 0.0
    effort = inverse_dynamics(mid[:, 0], mid[:, 1], mid[:, 2], params)
    return t_ns, at_stamps[:, 0], effort
