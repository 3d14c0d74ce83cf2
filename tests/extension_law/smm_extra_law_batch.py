"""The batched twin of :mod:`smm_extra_law`'s linear PD (one config per run), for sweeps."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from smm_analysis.batch.chain import BatchLaw, Reference
from smm_extra_law import LinearPDConfig


class BatchLinearPD(BatchLaw):
    """tau = k_p e + k_d e' per run, (N, 2)."""

    def __init__(self, configs: Sequence[LinearPDConfig], _model: Any = None) -> None:
        self.kp = np.array([c.kp for c in configs])
        self.kd = np.array([c.kd for c in configs])
        self.uses_observer = np.zeros(len(configs), dtype=bool)

    def step(
        self, reference: Reference, q: np.ndarray, qd: np.ndarray, xi: np.ndarray, dt: float
    ) -> np.ndarray:
        """The torque (N m), (N, 2)."""
        tau: np.ndarray = self.kp * (reference[0] - q) + self.kd * (reference[1] - qd)
        return tau
