"""The controller's nominal model on plain floats (M, C q', G of smm_dynamics, no friction).

The model-based algorithms (FLESO, FPDESO) need M(q), M^-1(q), C(q, q') q' and G(q) several times per
control step. This adapter evaluates them through smm_dynamics and returns plain floats so that the
2x2 algebra of the control laws runs without numpy call overhead.
"""

from __future__ import annotations

import numpy as np
from smm_dynamics import SMMParameters, coriolis_vector, gravity_vector, mass_matrix

__all__ = ["NominalModel"]


class NominalModel:
    """Rigid-body terms of the controller's model (its parameters, not the plant's).

    Args:
        params: Nominal SMM parameters. Friction is never used: no controller knows it (SPEC 1).
    """

    def __init__(self, params: SMMParameters) -> None:
        if not isinstance(params, SMMParameters):
            raise ValueError(f"params must be SMMParameters, got {type(params).__name__}")
        self.params = params

    def mass(self, alpha: float, beta: float) -> tuple[float, float, float]:
        """Entries (M11, M12, M22) of the symmetric inertia matrix M(q) (kg m^2)."""
        m = mass_matrix(np.array((alpha, beta)), self.params)
        return float(m[0, 0]), float(m[0, 1]), float(m[1, 1])

    def bias(
        self, alpha: float, beta: float, alpha_dot: float, beta_dot: float
    ) -> tuple[float, float, float, float, float, float, float]:
        """M entries and the bias torques at (q, q').

        Returns:
            (M11, M12, M22, (C q')_alpha, (C q')_beta, G_alpha, G_beta); M in kg m^2, torques in N m.
        """
        q = np.array((alpha, beta))
        m = mass_matrix(q, self.params)
        c = coriolis_vector(q, np.array((alpha_dot, beta_dot)), self.params)
        g = gravity_vector(q, self.params)
        return (
            float(m[0, 0]),
            float(m[0, 1]),
            float(m[1, 1]),
            float(c[0]),
            float(c[1]),
            float(g[0]),
            float(g[1]),
        )
