"""Simulation scenarios of SPEC section 3 (paper Section V.A), as data.

All scenarios start at rest at q = 0. The reference is either a step to ``amplitude`` at t = 0, the
sinusoid of eq. 41, ``q_d = amplitude * sin(angular_frequency * t)``, with analytic derivatives, or (the
``excite`` scenario, for identification, not one of the paper's) the default excitation series
:class:`smm_controller.excitation.ExcitationReference`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Literal

from smm_controller.reference import ExcitationReference, SineReference, StepReference
from smm_sim.plant import DISTURBANCE_MODELS, DisturbanceModel

from smm_analysis.errors import UnknownScenarioError

__all__ = ["ALL_SCENARIOS", "SCENARIOS", "Scenario", "get_scenario"]

ReferenceKind = Literal["step", "sine", "excite"]


@dataclass(frozen=True)
class Scenario:
    """One simulation scenario.

    Attributes:
        name: Identifier (``step``, ``case1``, ``case2``).
        description: One line for reports.
        duration: Simulated time t_f (s), > 0.
        reference_kind: ``"step"`` (step to ``amplitude`` at t = 0), ``"sine"`` (eq. 41) or ``"excite"``
            (the default :class:`ExcitationReference`; ``amplitude`` unused).
        amplitude: Step target or sine amplitude (alpha, beta) (rad).
        angular_frequency: Angular frequency of the sine (rad/s), > 0; unused for a step.
        noise_std: Encoder noise standard deviation (alpha, beta) (rad), >= 0.
        disturbance: External disturbance model of the plant (``"none"`` or ``"eq46"``).
        inertia_scale: Factor on the true plant's inertias (model error; 1.0 = none), > 0.
    """

    name: str
    description: str
    duration: float
    reference_kind: ReferenceKind
    amplitude: tuple[float, float]
    angular_frequency: float = math.pi
    noise_std: tuple[float, float] = (0.0, 0.0)
    disturbance: DisturbanceModel = "none"
    inertia_scale: float = 1.0

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError(f"name must be a non-empty string, got {self.name!r}")
        if not math.isfinite(self.duration) or self.duration <= 0.0:
            raise ValueError(f"duration must be a finite number > 0 s, got {self.duration!r}")
        if self.reference_kind not in ("step", "sine", "excite"):
            raise ValueError(
                f"reference_kind must be 'step', 'sine' or 'excite', got {self.reference_kind!r}"
            )
        if len(self.amplitude) != 2 or not all(math.isfinite(value) for value in self.amplitude):
            raise ValueError(f"amplitude must be 2 finite floats (alpha, beta), got {self.amplitude!r}")
        if not math.isfinite(self.angular_frequency) or self.angular_frequency <= 0.0:
            raise ValueError(
                f"angular_frequency must be a finite number > 0 rad/s, got {self.angular_frequency!r}"
            )
        if len(self.noise_std) != 2 or not all(math.isfinite(v) and v >= 0.0 for v in self.noise_std):
            raise ValueError(f"noise_std must be 2 finite floats >= 0 rad, got {self.noise_std!r}")
        if self.disturbance not in DISTURBANCE_MODELS:
            raise ValueError(f"disturbance must be one of {DISTURBANCE_MODELS}, got {self.disturbance!r}")
        if not math.isfinite(self.inertia_scale) or self.inertia_scale <= 0.0:
            raise ValueError(f"inertia_scale must be a finite number > 0, got {self.inertia_scale!r}")

    @property
    def is_step(self) -> bool:
        """True for a step reference (step metrics apply)."""
        return self.reference_kind == "step"

    def reference(self) -> StepReference | SineReference | ExcitationReference:
        """The reference generator q_d(t) -> shape (3, 2) (position, velocity, acceleration)."""
        if self.reference_kind == "step":
            return StepReference(amplitude=self.amplitude)
        if self.reference_kind == "excite":
            return ExcitationReference()
        return SineReference(amplitude=self.amplitude, angular_frequency=self.angular_frequency)

    def with_duration(self, duration: float) -> Scenario:
        """The same scenario with another length (s), e.g. shortened for tests."""
        return dataclasses.replace(self, duration=duration)


_PAPER_AMPLITUDE = (1.0, 0.785)

SCENARIOS: Mapping[str, Scenario] = MappingProxyType(
    {
        "step": Scenario(
            name="step",
            description="step to [1.0, 0.785] rad at t = 0, nominal plant (Figs 12-13)",
            duration=1.0,
            reference_kind="step",
            amplitude=_PAPER_AMPLITUDE,
        ),
        "case1": Scenario(
            name="case1",
            description="sinusoid of eq. 41, nominal plant, no noise, no disturbance (Figs 14-17, Table 3)",
            duration=5.0,
            reference_kind="sine",
            amplitude=_PAPER_AMPLITUDE,
        ),
        "case2": Scenario(
            name="case2",
            description=(
                "sinusoid of eq. 41, noise std 0.001 rad, eq. 46 disturbance, plant inertias +10 % "
                "(Figs 19-20, Table 4)"
            ),
            duration=5.0,
            reference_kind="sine",
            amplitude=_PAPER_AMPLITUDE,
            noise_std=(0.001, 0.001),
            disturbance="eq46",
            inertia_scale=1.1,
        ),
    }
)
"""The three scenarios of SPEC section 3, by name, in the order of the paper."""

_EXCITATION = ExcitationReference()

ALL_SCENARIOS: Mapping[str, Scenario] = MappingProxyType(
    {
        **SCENARIOS,
        "excite": Scenario(
            name="excite",
            description=(
                "identification run: the default excitation series on the case2 plant (inertias +10 %, "
                "noise std 0.001 rad), no external disturbance"
            ),
            duration=_EXCITATION.duration + 0.5,
            reference_kind="excite",
            amplitude=(0.0, 0.0),
            noise_std=(0.001, 0.001),
            inertia_scale=1.1,
        ),
    }
)
"""SCENARIOS and the ``excite`` identification run (docs/IDENTIFICATION.md), which is not a paper scenario:
the reproduction runs SCENARIOS only."""


def get_scenario(name: str) -> Scenario:
    """Looks up a scenario of :data:`ALL_SCENARIOS`.

    Raises:
        UnknownScenarioError: ``name`` is not a known scenario.
    """
    try:
        return ALL_SCENARIOS[name]
    except KeyError:
        raise UnknownScenarioError(f"unknown scenario {name!r}; known: {', '.join(ALL_SCENARIOS)}") from None
