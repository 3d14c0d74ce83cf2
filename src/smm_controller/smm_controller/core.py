"""What ``controller_node`` does per measurement, without ROS: :class:`ControllerCore` (times passed in).

Admission (the stamp policy of ``smm_node_runtime.admission`` and the plausibility check), the reference
clock, the chain or the law alone, law switching and reconfiguration, the output limits and the internals.
A step gives a :class:`Command` or a :class:`Refusal`. The node and the direct loop are glue around it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final, NamedTuple

import numpy as np
from smm_node_runtime.admission import (
    OUTPUTS_TOPIC,
    InputAdmission,
    Verdict,
    implausible_text,
    output_failure_text,
)
from smm_node_runtime.stamp_gate import Admission

from smm_controller._validation import FloatArray
from smm_controller.chain import ControlChain, JointController, build_chain, limited_torque, stage_internals
from smm_controller.fleso import FLESOConfig
from smm_controller.laws import get_law, law_table
from smm_controller.limits import MeasurementLimits, OutputLimitConfig, OutputLimiter, PlausibilityCheck
from smm_controller.reference import ReferenceClock, ReferenceGenerator
from smm_controller.td import TrackingDifferentiatorConfig
from smm_dynamics import SMMParameters

__all__ = ["MAX_CATCH_UP_PERIODS", "Command", "ControllerCore", "CoreSettings", "Refusal", "StepResult"]

MAX_CATCH_UP_PERIODS: Final[int] = 100
"""Most control periods the estimators catch up before a step (docs/DESIGN.md, "Missed periods")."""

_ZERO_REFERENCE: Final[tuple[tuple[float, float], ...]] = ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))


class Command(NamedTuple):
    """A torque to send for a measurement.

    Attributes:
        stamp_ns: The measurement's stamp (ns).
        torque: (tau_alpha, tau_beta) (N m), finite.
        verdict: What the stamp policy said (a time jump is logged by the caller).
        duplicate: True when the measurement re-sent the last answered stamp: the torque is the last one.
    """

    stamp_ns: int
    torque: tuple[float, float]
    verdict: Verdict
    duplicate: bool = False


class Refusal(NamedTuple):
    """No torque for a measurement, and why (already counted in ``counter`` of the admission's counters).

    Attributes:
        stamp_ns: The measurement's stamp (ns).
        counter: ``dropped_stale``, ``dropped_implausible``, ``invalid_outputs`` (the chain failed), ...
        message: The reason, one line.
        topic: The topic to warn about it under.
    """

    stamp_ns: int
    counter: str
    message: str
    topic: str

    @property
    def chain_failed(self) -> bool:
        """True when the chain stepped but gave no valid torque (not a refused input)."""
        return self.counter == "invalid_outputs"


StepResult = Command | Refusal
"""What one measurement gives."""


@dataclass(frozen=True)
class CoreSettings:
    """Everything a core is built from (the node's parameters at start-up).

    Attributes:
        algorithm: The running law's name.
        gains: Per law name, its current config.
        model: The nominal model.
        output_limits: Torque and rate limits after the law.
        control_period: dt of every step (s).
        chain: True: TD -> FLESO -> law here (the fused chain); False: the law alone, on filtered inputs.
        td: TD parameters (fused chain).
        fleso: FLESO parameters (fused chain, laws that use the disturbance estimate).
        measurement_limits: Plausible range and step of the joints (fused chain).
    """

    algorithm: str
    gains: Mapping[str, Any]
    model: SMMParameters
    output_limits: OutputLimitConfig
    control_period: float
    chain: bool
    td: TrackingDifferentiatorConfig
    fleso: FLESOConfig
    measurement_limits: MeasurementLimits


class ControllerCore:
    """The controller per measurement, pure (no ROS, times passed in).

    Args:
        settings: The configs it starts with.
        admission: The stamp gate and counters it shares with its node.
        reference: Gives the reference generator to sample at each stamp, or None when the reference comes
            with the inputs (:meth:`step` is then given its rows).
        announce: Called with one-line notes (the reference's t = 0), e.g. a logger's ``info``.
    """

    def __init__(
        self,
        settings: CoreSettings,
        admission: InputAdmission,
        reference: Callable[[], ReferenceGenerator] | None = None,
        announce: Callable[[str], object] | None = None,
    ) -> None:
        self.admission = admission
        self.control_period = settings.control_period
        self.period_ns = round(settings.control_period * 1_000_000_000)
        self.gains: dict[str, Any] = dict(settings.gains)
        self.model = settings.model
        self.td = settings.td
        self.fleso = settings.fleso
        self.limiter = OutputLimiter(settings.output_limits)
        """Torque and rate limits after the law (shared with the chain: one clamp count)."""
        self.plausibility = PlausibilityCheck(settings.measurement_limits) if settings.chain else None
        """Range and step check of the raw measurement (fused chain only)."""
        self.fused = settings.chain
        self._reference = reference
        self._announce = announce
        self.reference_clock = ReferenceClock(announce)
        """Time of the sampled reference: t = 0 at the first answered stamp (sampled reference only)."""
        self.last_reference: Sequence[Sequence[float]] = _ZERO_REFERENCE
        """Reference rows of the last step (3x2)."""
        self._ahead_rows: tuple[ReferenceGenerator, int, Sequence[Sequence[float]]] | None = None
        """(generator, stamp ns, its rows) sampled ahead by :meth:`prepare`."""
        self.chain: ControlChain | None = None
        """TD -> FLESO -> law (fused chain), else None."""
        self._last_command = (0.0, 0.0)
        self._stepped_ns: int | None = None
        """Stamp of the chain's last step (ns), None before the first and after a reset."""
        self._last_answer: Command | None = None
        self.algorithm = settings.algorithm
        self.law = self._build(self.algorithm)

    # -------------------------------------------------------------------------------- laws and settings

    def _build(self, name: str) -> JointController:
        """Builds law ``name`` with its current gains; in the fused chain, a fresh chain around it."""
        law: JointController = get_law(name).build(self.gains[name], self.model)
        if self.fused:
            self.chain = build_chain(
                name, self.model, law=law, td=self.td, fleso=self.fleso, limiter=self.limiter
            )
            self._last_command = (0.0, 0.0)
            self._stepped_ns = None  # a fresh chain has no missed periods to catch up
        return law

    @property
    def uses_disturbance_estimate(self) -> bool:
        """True when the running law takes the FLESO's estimate."""
        return bool(get_law(self.algorithm).uses_disturbance_estimate)

    def switch_refusal(self, algorithm: str, idle_time: float, quiet_s: float | None) -> str | None:
        """Why law ``algorithm`` may not take over now, or None when it may.

        Args:
            algorithm: The candidate law.
            idle_time: Quiet time a switch needs (s).
            quiet_s: Time since the last input (s), None before any.
        """
        if quiet_s is None or algorithm == self.algorithm or quiet_s >= idle_time:
            return None
        return (
            f"algorithm cannot change from {self.algorithm!r} to {algorithm!r} while the loop "
            f"is active: last input {quiet_s:.3f} s ago, switch_idle_time = {idle_time} s "
            "(no law can take over bumplessly; stop the plant first)"
        )

    def switch(self, algorithm: str) -> None:
        """Law ``algorithm`` runs from the next step, built fresh with its current gains."""
        if algorithm != self.algorithm:
            get_law(algorithm)  # unknown names raise before anything changes
            self.algorithm = algorithm
            self.law = self._build(algorithm)

    def set_gains(self, name: str, config: Any) -> None:
        """New gains of law ``name``; the running law takes them in place (a PID keeps its integrator)."""
        self.gains[name] = config
        if name == self.algorithm:
            get_law(name).reconfigure(self.law, config, self.model)

    def set_model(self, model: SMMParameters) -> None:
        """A new nominal model for the running law (when it uses one) and the FLESO."""
        self.model = model
        if get_law(self.algorithm).uses_model:
            get_law(self.algorithm).reconfigure(self.law, self.gains[self.algorithm], model)
        self.set_fleso(self.fleso)

    def set_td(self, config: TrackingDifferentiatorConfig) -> None:
        """New TD parameters (fused chain)."""
        self.td = config
        if self.chain is not None:
            self.chain.td.reconfigure(config)

    def set_fleso(self, config: FLESOConfig) -> None:
        """New FLESO parameters (fused chain, when the law uses the disturbance estimate)."""
        self.fleso = config
        if self.chain is not None and self.chain.fleso is not None:
            self.chain.fleso.reconfigure(config, params=self.model)

    def set_output_limits(self, config: OutputLimitConfig) -> None:
        """New torque and rate limits."""
        self.limiter.reconfigure(config)

    def set_measurement_limits(self, limits: MeasurementLimits) -> None:
        """New plausible range and step of the joints (fused chain)."""
        if self.plausibility is not None:
            self.plausibility.reconfigure(limits)

    def reset(self) -> None:
        """Every stage's state, the reference time and the last command start anew (a new run)."""
        self.law.reset()
        if self.chain is not None:
            self.chain.reset()
        self.limiter.reset()
        if self.plausibility is not None:
            self.plausibility.reset()
        self.reference_clock = ReferenceClock(self._announce)
        self._ahead_rows = None
        self._last_command = (0.0, 0.0)
        self._stepped_ns = None

    # --------------------------------------------------------------------------------------- per step

    def implausible(self, topic: str, stamp_ns: int, position: tuple[float, float]) -> Refusal | None:
        """The plausibility check of a raw measurement (rad) admitted by the stamp policy (counted)."""
        if self.plausibility is None:
            return None
        reason = self.plausibility.admit(position, stamp_ns, self.period_ns)
        if reason is None:
            return None
        message = implausible_text(topic, stamp_ns, reason)
        self.admission.refuse("dropped_implausible", message)
        return Refusal(stamp_ns, "dropped_implausible", message, topic)

    def reference_rows(self, stamp_ns: int) -> Sequence[Sequence[float]]:
        """The sampled reference at ``stamp_ns`` (3x2 floats; the reference clock's t = 0 is the first).

        Raises:
            RuntimeError: The core samples no reference.
        """
        if self._reference is None:
            raise RuntimeError("this core samples no reference: its steps are given the rows")
        generator = self._reference()
        ahead = self._ahead_rows
        if ahead is not None and ahead[0] is generator and ahead[1] == stamp_ns:
            return ahead[2]
        return generator.rows(self.reference_clock.time_s(stamp_ns))

    def step(
        self,
        stamp_ns: int,
        position: tuple[float, float],
        effort: tuple[float, float] | None,
        reference: Sequence[Sequence[float]],
    ) -> tuple[float, float]:
        """One step of the fused chain on a validated measurement (rad; applied torque N m or None).

        Returns:
            The limited torque (N m), possibly non-finite (the caller refuses it).
        """
        assert self.chain is not None, "step() runs the fused chain; step_law() the law alone"
        self.last_reference = reference
        applied = effort if effort is not None else self._last_command
        missed = self.missed_periods(stamp_ns)
        if missed:
            self.chain.advance_estimators(position, applied, self.control_period, missed)
        self._stepped_ns = stamp_ns
        torque = self.chain.step_floats(position, applied, reference, self.control_period)
        if math.isfinite(torque[0]) and math.isfinite(torque[1]):
            self._last_command = torque  # the applied torque of the next step when the plant gives none
        return torque

    def missed_periods(self, stamp_ns: int) -> int:
        """Control periods between the last step and ``stamp_ns`` that had no step (0 for the next period).

        0 before the first step, after a reset, and for a gap beyond the stamp gate's window or
        :data:`MAX_CATCH_UP_PERIODS` (a time jump: the step is one period, docs/NODES.md).
        """
        last = self._stepped_ns
        if last is None or stamp_ns <= last or stamp_ns - last > self.admission.gate.max_ahead_ns:
            return 0
        missed = round((stamp_ns - last) / self.period_ns) - 1
        return missed if 0 < missed <= MAX_CATCH_UP_PERIODS else 0

    def prepare(self) -> None:
        """The work of the next step that needs no measurement, done ahead (optional; the same steps).

        The fused chain's (:meth:`ControlChain.prepare`) and the sampled reference one control period
        after the last answered stamp. The direct loop calls it after its send, before the next measurement.
        """
        if self.chain is not None:
            self.chain.prepare(self.control_period)
        last = self.admission.gate.last_stamp_ns
        started = self.reference_clock.first_stamp_ns is not None
        if self._reference is not None and last is not None and started:
            stamp = last + self.period_ns
            generator = self._reference()
            self._ahead_rows = (generator, stamp, generator.rows(self.reference_clock.time_s(stamp)))

    def step_law(
        self,
        position: tuple[float, float],
        velocity: tuple[float, float],
        disturbance: tuple[float, float],
        reference: Sequence[Sequence[float]],
    ) -> tuple[float, float]:
        """Step 4 of the chain alone, on filtered inputs (rad, rad/s; xi~ N m): the limited torque (N m)."""
        self.last_reference = reference
        return limited_torque(
            self.law,
            self.limiter,
            reference,
            position,
            velocity,
            disturbance=disturbance,
            dt=self.control_period,
        )

    def measurement(
        self,
        topic: str,
        stamp_ns: int,
        position: tuple[float, float],
        effort: tuple[float, float] | None,
        clock_ns: int,
    ) -> StepResult:
        """Everything for one raw measurement with the sampled reference: admission, chain, limits.

        Args:
            topic: Where it came from (for the counters' messages).
            stamp_ns: Its stamp (ns).
            position: Measured position (rad), finite.
            effort: Torque applied during the last interval (N m), finite; None: the last command.
            clock_ns: The node's clock (ns), for the stamp policy's future check.

        Returns:
            The torque to send (the last one again for a re-sent stamp), or why there is none.
        """
        verdict = self.admission.admit(topic, stamp_ns, (position, effort), clock_ns)
        if verdict.admission is not Admission.NEW:  # a new stamp, the common case, needs none of this
            answer = self._not_new(verdict, stamp_ns, topic)
            if answer is not None:
                return answer
        refused = self.implausible(topic, stamp_ns, position)
        if refused is not None:
            return refused
        self.admission.mark_answered(stamp_ns)
        self._last_answer = None
        try:
            torque = self.step(stamp_ns, position, effort, self.reference_rows(stamp_ns))
        except (ValueError, ArithmeticError) as error:
            return self._failed(stamp_ns, error)
        if not (math.isfinite(torque[0]) and math.isfinite(torque[1])):
            return self._failed(stamp_ns, ValueError(f"torque must be finite, got {torque!r}"))
        answer = Command(stamp_ns, torque, verdict)
        self._last_answer = answer
        return answer

    def _not_new(self, verdict: Verdict, stamp_ns: int, topic: str) -> StepResult | None:
        """The answer to a stamp the gate did not find new; None after a time jump (it is stepped)."""
        if verdict.admission is Admission.RESYNC and verdict.backward:
            self.reset()
        if verdict.answer_again:
            last = self._last_answer
            if last is not None and last.stamp_ns == stamp_ns:
                return last._replace(verdict=verdict, duplicate=True)
            return Refusal(stamp_ns, "duplicates_answered", "re-sent stamp whose step gave no torque", topic)
        if not verdict.accepted:
            assert verdict.counter is not None
            return Refusal(stamp_ns, verdict.counter, verdict.message, topic)
        return None

    def _failed(self, stamp_ns: int, error: Exception) -> Refusal:
        message = output_failure_text(stamp_ns, error)
        self.admission.refuse("invalid_outputs", message)
        return Refusal(stamp_ns, "invalid_outputs", message, OUTPUTS_TOPIC)

    # -------------------------------------------------------------------------------------- internals

    def internals(self) -> Mapping[str, FloatArray]:
        """Every stage's internals (``td.``, ``fleso.``, ``controller.``, ``limiter.``, ...), each (2,)."""
        if self.chain is not None:
            return self.chain.internals
        return {
            **stage_internals("controller", self.law.internals),
            **stage_internals("limiter", self.limiter.internals),
        }

    def internals_rows(self) -> dict[str, FloatArray]:
        """:meth:`internals` and the admission's counters: the rows of ``controller_internals``."""
        return {**self.internals(), **self.admission.counters.rows()}

    def last_reference_array(self) -> FloatArray:
        """The reference of the last step, (3, 2)."""
        return np.array(self.last_reference)


def default_gains() -> dict[str, Any]:
    """Every law's default config, by name."""
    return {name: law.config() for name, law in law_table().items()}
