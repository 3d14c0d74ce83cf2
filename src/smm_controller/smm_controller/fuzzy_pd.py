"""Fuzzy PD gain schedule (paper eq. 12, Tables 1 and 7; SPEC section 4).

Per joint: k_p = k_p0 + k1 f(k_e), k_d = k_d0 + k2 f(k_de), the f from the Mamdani rule base of
:mod:`rules` on the clipped, scaled error and error rate; both joints and outputs in one batched
evaluation (docs/DESIGN.md, "Fuzzy PD gain schedule").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from smm_schema.ranges import above, at_least, check_bounds

from smm_controller._validation import (
    FloatArray,
    as_joint_vector,
    check_instance,
    internals_view,
)
from smm_controller.fuzzy_batch import MamdaniBatch
from smm_controller.rules import TABLE_1, TABLE_7, RuleTable, pd_gain_system

__all__ = [
    "PAPER_FPDESO_FUZZY",
    "PAPER_FPD_FUZZY",
    "FuzzyPDConfig",
    "FuzzyPDGainSchedule",
]


@dataclass(frozen=True)
class FuzzyPDConfig:
    """Fuzzy PD gain schedule parameters, per joint (alpha, beta); defaults: paper FPDESO gains.

    Attributes:
        k_e: Error scaling to the normalised input e~ (1/rad), > 0.
        k_de: Error-rate scaling to ce~ (s/rad), > 0.
        k1: Scale of the fuzzy output f(k_e) on k_p, >= 0 and < kp0.
        k2: Scale of the fuzzy output f(k_de) on k_d, >= 0 and < kd0.
        kp0: Base proportional gain, > 0.
        kd0: Base derivative gain, > 0.
        grid_points: Defuzzification grid size over [-1, 1], integer >= 3.

    k1 < kp0 and k2 < kd0 keep both gains positive for every fuzzy output in [-1, 1] (the stability
    proof of Section IV needs positive definite K_p and K_d).
    """

    k_e: tuple[float, float] = field(default=(2.0, 6.0), metadata=above(0.0))
    k_de: tuple[float, float] = field(default=(5.0, 2.0), metadata=above(0.0))
    k1: tuple[float, float] = field(default=(10.0, 13.0), metadata=at_least(0.0))
    k2: tuple[float, float] = field(default=(0.5, 0.9), metadata=at_least(0.0))
    kp0: tuple[float, float] = field(default=(4050.0, 4150.0), metadata=above(0.0))
    kd0: tuple[float, float] = field(default=(110.0, 90.0), metadata=above(0.0))
    grid_points: int = field(default=201, metadata=at_least(3))

    def __post_init__(self) -> None:
        check_bounds(self)
        for scale_name, scale, base_name, base in (
            ("k1", self.k1, "kp0", self.kp0),
            ("k2", self.k2, "kd0", self.kd0),
        ):
            if any(s >= b for s, b in zip(scale, base, strict=True)):
                raise ValueError(
                    f"{scale_name} must be < {base_name} per joint so the gain stays positive, "
                    f"got {scale_name}={scale!r}, {base_name}={base!r}"
                )


#: Paper gains of the FPDESO controller (Section V.A).
PAPER_FPDESO_FUZZY = FuzzyPDConfig()
#: Paper gains of the FPD baseline (Section V.A, item 4).
PAPER_FPD_FUZZY = FuzzyPDConfig(
    k_e=(8.0, 5.0), k_de=(2.0, 3.0), k1=(1.5, 5.0), k2=(0.5, 0.8), kp0=(41.0, 45.0), kd0=(1.1, 0.9)
)


def _gain_batch(tables: tuple[RuleTable, RuleTable], grid_points: int) -> MamdaniBatch:
    """The gain rule bases (alpha, beta), defuzzified on ``grid_points`` points."""
    return MamdaniBatch([pd_gain_system(table, grid_points) for table in tables])


def _clip_unit(x: float) -> float:
    return -1.0 if x < -1.0 else (1.0 if x > 1.0 else x)


class FuzzyPDGainSchedule:
    """Gain schedule k_p(e, e'), k_d(e, e') of eq. 12 for both joints.

    Args:
        config: Gains (default: paper FPDESO gains).
        tables: Rule tables (alpha, beta), rows ce, columns e (default: Tables 1 and 7).
    """

    def __init__(
        self,
        config: FuzzyPDConfig | None = None,
        tables: tuple[RuleTable, RuleTable] = (TABLE_1, TABLE_7),
    ) -> None:
        self.config = config if config is not None else FuzzyPDConfig()
        self._tables = tables
        self._batch = _gain_batch(tables, self.config.grid_points)
        self.reset()

    def reset(self) -> None:
        """The schedule is memoryless; this only clears the recorded internals."""
        self._last: tuple[float, ...] = (0.0,) * 12

    def reconfigure(self, config: FuzzyPDConfig) -> None:
        """Takes new gains for the next step, with the same rule tables.

        The fuzzy systems are rebuilt when ``grid_points`` changes; the recorded internals are kept until
        the next step.

        Args:
            config: The new gains (replaces the config whole).

        Raises:
            TypeError: ``config`` is not a :class:`FuzzyPDConfig`.
        """
        check_instance("config", config, FuzzyPDConfig)
        if config.grid_points != self.config.grid_points:
            self._batch = _gain_batch(self._tables, config.grid_points)
        self.config = config

    def step(self, e: npt.ArrayLike, e_dot: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Gains for the current error.

        Args:
            e: Tracking error q_d - q (rad), shape (2,).
            e_dot: Error rate q_d' - q' (rad/s), shape (2,).

        Returns:
            (kp, kd), each shape (2,).
        """
        e0, e1 = as_joint_vector("e", e)
        ed0, ed1 = as_joint_vector("e_dot", e_dot)
        kp0, kp1, kd0, kd1 = self.step_floats(e0, e1, ed0, ed1)
        return np.array((kp0, kp1)), np.array((kd0, kd1))

    def step_floats(self, e0: float, e1: float, ed0: float, ed1: float) -> tuple[float, float, float, float]:
        """Same as :meth:`step` on floats: returns (kp_alpha, kp_beta, kd_alpha, kd_beta)."""
        config = self.config
        (k_e0, k_e1), (k_de0, k_de1) = config.k_e, config.k_de
        x0 = _clip_unit(k_e0 * e0)
        x1 = _clip_unit(k_e1 * e1)
        c0 = _clip_unit(k_de0 * ed0)
        c1 = _clip_unit(k_de1 * ed1)
        fe0, fde0, fe1, fde1 = self._batch.evaluate_flat(((x0, c0), (x1, c1)))
        (kp00, kp01), (k10, k11) = config.kp0, config.k1
        (kd00, kd01), (k20, k21) = config.kd0, config.k2
        kp0 = kp00 + k10 * fe0
        kp1 = kp01 + k11 * fe1
        kd0 = kd00 + k20 * fde0
        kd1 = kd01 + k21 * fde1
        self._last = (x0, x1, c0, c1, fe0, fe1, fde0, fde1, kp0, kp1, kd0, kd1)
        return kp0, kp1, kd0, kd1

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """Read-only copies, shape (2,): e_normalised, ce_normalised, f_ke, f_kde, kp, kd."""
        return internals_view(("e_normalised", "ce_normalised", "f_ke", "f_kde", "kp", "kd"), self._last)
