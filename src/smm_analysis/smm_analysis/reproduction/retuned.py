"""Clearly labelled retuned gain sets, run beside the paper's (SPEC section 4; issue #3).

Each set is data: the gains, and what it changes, by how much, by what rule and why. The only set,
``fpdeso_retuned``, gives FPDESO's beta the damping ratio of the paper's alpha gains (k_d0 90 -> 111 1/s)
to bring the 1 kHz beta step under the 5 % overshoot bound: docs/REPRODUCTION.md, "The retuned FPDESO set";
docs/METRICS.md, "smm-reproduce".
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from smm_controller.laws import law_table

from smm_controller import FPDESOConfig, FPDESOController, JointController
from smm_dynamics import SMMParameters

__all__ = [
    "FPDESO_RETUNED",
    "RETUNED_SETS",
    "RetunedSet",
    "controller_label",
    "damping_ratio",
    "matched_damping_kd0",
]


@dataclass(frozen=True)
class RetunedSet:
    """A labelled gain set that replaces a paper controller's gains, run beside it.

    Attributes:
        name: Pseudo-controller name (key in metrics.json, ``--controllers``).
        base: The paper controller whose chain (TD, FLESO) and law it uses, e.g. ``"fpdeso"``.
        label: Human label for tables and plots; says what differs from the paper.
        config: The full controller configuration.
        change: What was changed, by how much and by what rule, in one sentence.
        reason: Why, in one sentence.
    """

    name: str
    base: str
    label: str
    config: FPDESOConfig
    change: str
    reason: str

    def make_controller(self, model_params: SMMParameters) -> JointController:
        """A controller with this set's gains on the nominal model ``model_params``."""
        return FPDESOController(self.config, model_params)


def damping_ratio(kp: float, kd: float) -> float:
    """Damping ratio kd / (2 sqrt(kp)) of e'' + kd e' + kp e = 0 (kp in 1/s^2 > 0, kd in 1/s)."""
    return kd / (2.0 * math.sqrt(kp))


def matched_damping_kd0(config: FPDESOConfig, source: int = 0, target: int = 1) -> float:
    """k_d0 of joint ``target`` that gives it the damping ratio of joint ``source`` at its own k_p0.

    k_d0[target] = 2 zeta[source] sqrt(k_p0[target]) = k_d0[source] sqrt(k_p0[target] / k_p0[source]).

    Args:
        config: The gain set to read k_p0 and k_d0 from.
        source: Joint index (0 alpha, 1 beta) whose damping ratio is copied.
        target: Joint index that receives it.

    Returns:
        The unrounded k_d0 (1/s).
    """
    fuzzy = config.fuzzy
    zeta = damping_ratio(fuzzy.kp0[source], fuzzy.kd0[source])
    return 2.0 * zeta * math.sqrt(fuzzy.kp0[target])


_PAPER_FPDESO = FPDESOConfig()
_RETUNED_BETA_KD0 = 111.0
"""round(matched_damping_kd0(paper)) = round(110 sqrt(4150 / 4050)) = round(111.35); a test pins the rule."""

FPDESO_RETUNED = RetunedSet(
    name="fpdeso_retuned",
    base="fpdeso",
    label="FPDESO, retuned (beta k_d0 = 111, paper: 90)",
    config=dataclasses.replace(
        _PAPER_FPDESO,
        fuzzy=dataclasses.replace(_PAPER_FPDESO.fuzzy, kd0=(_PAPER_FPDESO.fuzzy.kd0[0], _RETUNED_BETA_KD0)),
    ),
    change=(
        "only beta's k_d0, from 90 to 111 1/s (+23 %), so that beta gets the damping ratio of the paper's "
        "alpha gains: k_d0_beta = 2 zeta_alpha sqrt(k_p0_beta) = 110 sqrt(4150 / 4050) = 111.35, rounded "
        "to 111; every other gain (k_p0, k1, k2, k_e, k_de, FLESO, b_d) and the TD are the paper's / the "
        "defaults, and the plant is untouched"
    ),
    reason=(
        "the paper's beta gains (k_p0 = 4150, k_d0 = 90) are a PD of damping ratio 0.699, whose "
        "continuous-time step already overshoots by 4.66 %; the phase lag of the 1 kHz loop takes it "
        "above the 5 % acceptance bound"
    ),
)
"""The paper's FPDESO gains with beta's k_d0 raised to match alpha's damping ratio."""

RETUNED_SETS: Mapping[str, RetunedSet] = MappingProxyType({FPDESO_RETUNED.name: FPDESO_RETUNED})
"""Every retuned set by pseudo-controller name."""


def controller_label(name: str) -> str:
    """Human label of a controller or retuned set (``FPDESO``, ``FPDESO, retuned (...)``)."""
    if name in RETUNED_SETS:
        return RETUNED_SETS[name].label
    law = law_table().get(name)
    return name if law is None else law.display
