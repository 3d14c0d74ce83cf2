"""The controller's nominal model on plain floats: M(q), C(q, q') q', G(q) (no friction).

The model-based algorithms (FLESO, FPDESO) need these terms several times per control step. The public
functions of ``smm_dynamics`` take and return numpy arrays (a few microseconds of call overhead each);
here the same closed-form entries (``smm_dynamics._generated``, plain arithmetic on floats) are
evaluated directly, and the 2x2 algebra stays on Python floats. A test pins every term against the
public ``smm_dynamics`` functions.

Within one control step the observer needs M at the TD position and the control law needs M and C at
the same position, so the last trigonometric values and inertia entries are memoised, and
:meth:`NominalModel.shared` lets algorithms built from equal parameters share one model.
"""

from __future__ import annotations

import math
import weakref
from typing import ClassVar

from smm_dynamics._generated import coriolis_matrix_entries, mass_matrix_entries

from smm_dynamics import SMMParameters

__all__ = ["NominalModel"]


class NominalModel:
    """Rigid-body terms of the controller's model (its parameters, not the plant's).

    Args:
        params: Nominal SMM parameters. Friction is never used: no controller knows it (SPEC 1).
    """

    _shared: ClassVar[weakref.WeakValueDictionary[SMMParameters, NominalModel]] = (
        weakref.WeakValueDictionary()
    )

    def __init__(self, params: SMMParameters) -> None:
        if not isinstance(params, SMMParameters):
            raise ValueError(f"params must be SMMParameters, got {type(params).__name__}")
        self.params = params
        self._inertias = (params.I11, params.I22, params.I44, params.I55)
        # G = dV/dq with V = gravity_sign m_c l_c g cos(beta): G = (0, -gravity_sign m_c l_c g sin(beta)).
        self._gravity_coefficient = -params.gravity_sign * params.mass_lever * params.gravity
        # (alpha, beta, sin a, cos a, sin b, cos b, M11, M12, M22) of the last position evaluated.
        self._memo = (math.nan,) * 9

    @classmethod
    def shared(cls, params: SMMParameters) -> NominalModel:
        """One model per parameter set, shared by the algorithms that use it (memo reuse)."""
        if not isinstance(params, SMMParameters):
            raise ValueError(f"params must be SMMParameters, got {type(params).__name__}")
        model = cls._shared.get(params)
        if model is None:
            model = cls(params)
            cls._shared[params] = model
        return model

    def _position_terms(self, alpha: float, beta: float) -> tuple[float, ...]:
        memo = self._memo
        if memo[0] == alpha and memo[1] == beta:
            return memo
        sa, ca, sb, cb = math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)
        m11, m12, m22 = mass_matrix_entries(sa, ca, sb, cb, *self._inertias)
        memo = (alpha, beta, sa, ca, sb, cb, m11, m12, m22)
        self._memo = memo
        return memo

    def mass(self, alpha: float, beta: float) -> tuple[float, float, float]:
        """Entries (M11, M12, M22) of the symmetric inertia matrix M(q) (kg m^2) at q (rad)."""
        memo = self._position_terms(alpha, beta)
        return memo[6], memo[7], memo[8]

    def bias(
        self, alpha: float, beta: float, alpha_dot: float, beta_dot: float
    ) -> tuple[float, float, float, float, float, float, float]:
        """M entries and the bias torques at (q, q') (rad, rad/s).

        Returns:
            (M11, M12, M22, (C q')_alpha, (C q')_beta, G_alpha, G_beta); M in kg m^2, torques in N m.
        """
        _, _, sa, ca, sb, cb, m11, m12, m22 = self._position_terms(alpha, beta)
        c11, c12, c21, c22 = coriolis_matrix_entries(
            sa, ca, sb, cb, alpha_dot, beta_dot, self._inertias[0], self._inertias[3]
        )
        return (
            m11,
            m12,
            m22,
            c11 * alpha_dot + c12 * beta_dot,
            c21 * alpha_dot + c22 * beta_dot,
            0.0,
            self._gravity_coefficient * sb,
        )
