"""The controller's nominal model on plain floats: M(q), C(q, q') q', G(q) and, when asked, F(q').

Built on the float fast path of ``smm_dynamics`` (docs/DYNAMICS.md), equal to its array functions up to
rounding (tested); the 2x2 algebra stays on Python floats, the last M is memoised per position, and
:meth:`NominalModel.shared` gives algorithms built from equal parameters one model.
"""

from __future__ import annotations

import math
import weakref
from typing import ClassVar

from smm_dynamics import SMMParameters, friction_floats, mass_matrix_floats, rigid_body_floats

__all__ = ["NominalModel"]


class NominalModel:
    """Rigid-body terms of the controller's model (its parameters, not the plant's).

    Args:
        params: Nominal SMM parameters. Friction is used only by laws whose ``compensate_friction``
            is set (off by default: the paper's laws know no friction, SPEC 1).
    """

    _shared: ClassVar[weakref.WeakValueDictionary[SMMParameters, NominalModel]] = (
        weakref.WeakValueDictionary()
    )

    def __init__(self, params: SMMParameters) -> None:
        if not isinstance(params, SMMParameters):
            raise ValueError(f"params must be SMMParameters, got {type(params).__name__}")
        self.params = params
        # (alpha, beta, M11, M12, M22) of the last position evaluated by mass().
        self._memo = (math.nan,) * 5

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

    def mass(self, alpha: float, beta: float) -> tuple[float, float, float]:
        """Entries (M11, M12, M22) of the symmetric inertia matrix M(q) (kg m^2) at q (rad)."""
        memo = self._memo
        if memo[0] == alpha and memo[1] == beta:
            return memo[2], memo[3], memo[4]
        m11, m12, m22 = mass_matrix_floats(alpha, beta, self.params)
        self._memo = (alpha, beta, m11, m12, m22)
        return m11, m12, m22

    def bias(
        self, alpha: float, beta: float, alpha_dot: float, beta_dot: float
    ) -> tuple[float, float, float, float, float, float, float]:
        """M entries and the bias torques at (q, q') (rad, rad/s).

        Returns:
            (M11, M12, M22, (C q')_alpha, (C q')_beta, G_alpha, G_beta); M in kg m^2, torques in N m.
            M is bit-identical to :meth:`mass` at the same position.
        """
        return rigid_body_floats(alpha, beta, alpha_dot, beta_dot, self.params)

    def friction(self, alpha_dot: float, beta_dot: float) -> tuple[float, float]:
        """Model friction F(q') = f_v q' + f_c sign(q') + offset (N m) at q' (rad/s)."""
        return friction_floats(alpha_dot, beta_dot, self.params)
