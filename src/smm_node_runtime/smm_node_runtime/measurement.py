"""Base class of the nodes that answer stamped measurements, and their drop counters (``docs/NODES.md``)."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Final, Unpack

import numpy as np
import numpy.typing as npt
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.publisher import Publisher
from smm_schema.ranges import bounds, check_bounds

from smm_node_runtime.admission import (
    COUNTER_ROWS,
    OUTPUTS_TOPIC,
    InputAdmission,
    InputCounters,
    Verdict,
    implausible_text,
    output_failure_text,
)
from smm_node_runtime.diagnostics import CountWindows, DiagnosticsPublisher, Health, Level, worst
from smm_node_runtime.node import NodeOptions, SmmNode
from smm_node_runtime.parameters import ConfigParameters
from smm_node_runtime.stamp_gate import DEFAULT_CONTROL_PERIOD, Admission, StampPolicy

__all__ = [
    "COUNTER_ROWS",
    "STAMP_PREFIX",
    "WARN_COUNTERS",
    "WARN_THROTTLE_S",
    "ControlPeriodConfig",
    "InputCounters",
    "MeasurementDrivenNode",
    "Output",
    "values_of",
]

STAMP_PREFIX: Final[str] = "stamp"
"""Parameters of :class:`StampPolicy` are ``stamp.<field>``."""

WARN_THROTTLE_S: Final[float] = 1.0
"""At most one warning per input topic and per this many seconds (s); the counters count every drop."""

Output = tuple[Publisher, Any]
"""A message ready to go: ``(publisher, message)``."""

_NS_PER_S: Final[int] = 1_000_000_000


@dataclass(frozen=True)
class ControlPeriodConfig:
    """The step size a node integrates its algorithm with (declared read-only: fixed at start-up).

    Attributes:
        control_period: Control period dt (s), in (0, 1]; must equal the plant's period (the
            simulator's ``control_period``), because nodes step once per measurement with this dt.
    """

    control_period: float = field(default=DEFAULT_CONTROL_PERIOD, metadata=bounds(0.0, 1.0, low_open=True))

    def __post_init__(self) -> None:
        check_bounds(self)


WARN_COUNTERS: Final[tuple[str, ...]] = (
    "dropped_invalid",
    "dropped_stale",
    "dropped_ahead",
    "dropped_future",
    "dropped_implausible",
    "conflicting_duplicates",
    "time_jumps",
)
"""Counters whose increase within the current or the last diagnostics period makes the status WARN."""

DEADLINE_MISS_WARN_FRACTION: Final[float] = 0.1
"""WARN when more than this fraction of the last period's steps took longer than the control period."""


_VALUE_ATTRIBUTES: Final[tuple[str, ...]] = ("position", "velocity", "effort", "values")


def values_of(item: object) -> tuple[tuple[float, ...], ...]:
    """Values of a parsed input (arrays ``position``, ``velocity``, ``effort``, ``values``), comparable."""
    found = (getattr(item, name, None) for name in _VALUE_ATTRIBUTES)
    return tuple(
        tuple(np.asarray(value, dtype=np.float64).ravel().tolist()) for value in found if value is not None
    )


class MeasurementDrivenNode(SmmNode):
    """Base class of a node that answers stamped measurements (policy: ``docs/NODES.md``).

    Declares ``control_period`` (read-only) and ``stamp.*`` (:class:`StampPolicy`) and publishes the
    node's status on ``/diagnostics`` (:meth:`health`). Subclasses: parse each input with the
    ``smm_msgs_py`` conversions inside ``try: ... except InterfaceError as error: self.reject(topic,
    error)``; call :meth:`admit` with the stamp (and the values, for the duplicate check) and return unless
    it is True; when the step for a stamp is done, build the output messages and hand them to
    :meth:`answer` (a conversion error there is counted as an invalid output and nothing is published).
    """

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        self.timing = ConfigParameters(self, "", ControlPeriodConfig(), read_only=True)
        self.stamp_policy = ConfigParameters(self, STAMP_PREFIX, StampPolicy(), on_change=self._on_policy)
        self.admission = InputAdmission(self.stamp_policy.config, self.timing.config.control_period)
        """Stamp gate, counters and last reason (pure; shared with a pure core of the node's algorithm)."""
        self._last_answer: tuple[Output, ...] = ()
        # Publishers the diagnostics went to, learnt from the first build: while none of them has a
        # subscriber, diagnostics are neither built nor published (lazy publishing, as image_transport
        # does), which is indistinguishable from publishing to nobody and halves the work per step.
        self._diagnostic_publishers: tuple[Publisher, ...] | None = None
        self._topic_loggers: dict[str, RcutilsLogger] = {}
        self._window = CountWindows({})  # every count starts at 0
        self.diagnostics = DiagnosticsPublisher(self, self.health, on_period=self._end_period)

    @property
    def control_period(self) -> float:
        """Step size dt of every step (s)."""
        return self.timing.config.control_period

    @property
    def period_ns(self) -> int:
        """Control period (ns)."""
        return round(self.control_period * _NS_PER_S)

    @property
    def last_answered_stamp_ns(self) -> int | None:
        """Stamp (ns) of the last measurement this node answered, None before the first."""
        return self.admission.gate.last_stamp_ns

    @property
    def counters(self) -> InputCounters:
        """What the node did not process normally, since start."""
        return self.admission.counters

    @property
    def inputs(self) -> int:
        """Inputs received (every topic, valid or not)."""
        return self.admission.inputs

    @property
    def answered(self) -> int:
        """Stamps answered."""
        return self.admission.answered

    @property
    def last_error(self) -> str:
        """The newest reason an input or output was dropped ("" before any)."""
        return self.admission.last_error

    def _on_policy(self, policy: StampPolicy) -> None:
        def set_policy() -> None:
            self.admission.gate.policy = policy

        self._apply(set_policy)

    def _apply(self, change: Callable[[], None]) -> None:
        """Applies a validated parameter change at once (a node whose steps a loop runs hands it over)."""
        change()

    def warn_throttled(self, topic: str, message: str) -> None:
        """Log a warning, at most once per :data:`WARN_THROTTLE_S` per ``topic`` (throttled per topic)."""
        logger = self._topic_loggers.get(topic)
        if logger is None:
            child_name = topic.strip("~/").replace("/", ".")
            logger = self.get_logger().get_child(child_name)  # type: ignore[no-untyped-call]
            self._topic_loggers[topic] = logger
        logger.warning(message, throttle_duration_sec=WARN_THROTTLE_S)

    def _refused(self, counter: str, topic: str, message: str) -> None:
        """Count a refused input in ``counter``, remember and warn about it (throttled), update the status."""
        self.admission.refuse(counter, message)
        self.warn_refused(topic, counter, message)

    def warn_refused(self, topic: str, counter: str, message: str) -> None:
        """Warn about an input or output already counted in ``counter`` (throttled); update the status."""
        self.warn_throttled(topic, f"{message}; {getattr(self.counters, counter)} {counter} so far")
        self.diagnostics.check()

    def reject(self, topic: str, error: Exception) -> None:
        """Drop an input that broke the interface contract: count it and warn (throttled)."""
        self.admission.inputs += 1
        self._refused(
            "dropped_invalid", topic, f"dropped input on '{topic}' ({type(error).__name__}: {error})"
        )

    def reject_implausible(self, topic: str, stamp_ns: int, reason: str) -> None:
        """Drop a measurement that is valid but physically implausible (after :meth:`admit` accepted it)."""
        self._refused("dropped_implausible", topic, implausible_text(topic, stamp_ns, reason))

    def admit(self, topic: str, stamp_ns: int, values: object = None) -> bool:
        """Apply the stamp policy to an input stamped ``stamp_ns`` (ns) on ``topic``.

        Args:
            topic: Input topic (for the counters and the warning).
            stamp_ns: The input's stamp (ns).
            values: The input's values in a comparable form (e.g. a tuple of floats), or None: a duplicate
                stamp is then answered only when its values equal those answered for that stamp.

        Returns:
            True when the stamp is new (the caller processes the input). False for a duplicate (the last
            answer has been re-published), a conflicting duplicate, or a refused stamp (each counted and
            warned about).
        """
        verdict = self.admission.admit(topic, stamp_ns, values, self.get_clock().now().nanoseconds)
        if verdict.admission is Admission.RESYNC:
            self.report(topic, verdict)
            self.on_time_jump(backward=verdict.backward)
            self.diagnostics.check()
            return True
        if verdict.answer_again:
            for publisher, message in self._last_answer:
                publisher.publish(message)
            return False
        self.report(topic, verdict)
        return verdict.accepted

    def report(self, topic: str, verdict: Verdict) -> None:
        """Logs what a verdict of :attr:`admission` says (time jump, dropped input); nothing for a new stamp.

        The verdict is counted already; a time jump is logged as a warning, a dropped input warned about
        (throttled) and the status updated.
        """
        if verdict.admission is Admission.RESYNC:
            self.get_logger().warning(  # type: ignore[no-untyped-call]
                f"{verdict.message} after {self.admission.gate.policy.resync_samples} consistent samples"
            )
        elif verdict.counter is not None and not verdict.answer_again:
            self.warn_refused(topic, verdict.counter, verdict.message)

    def on_time_jump(self, *, backward: bool) -> None:
        """Called when the node resynchronised after a time jump (``backward``: to older stamps, a new run).

        Subclasses forget what is tied to the old timeline (synchroniser, and for a new run the algorithm
        state and the reference time), so the new run starts as a fresh one would (``docs/NODES.md``).
        """

    def answer(
        self,
        stamp_ns: int,
        build_outputs: Callable[[], Sequence[Output]],
        build_diagnostics: Callable[[], Sequence[Output]] | None = None,
    ) -> bool:
        """Publish what answers ``stamp_ns`` (ns): the control-chain outputs, then the diagnostics.

        The stamp is marked answered even when building the outputs fails (the algorithm has stepped), so a
        re-transmission is not stepped again; it then gets no answer. Only the control-chain outputs are
        re-published for a re-transmission: a recorder never sees a diagnostic twice.

        Args:
            stamp_ns: Stamp of the answered measurement (ns), newer than the last answered one.
            build_outputs: Steps the algorithm and builds the control-chain ``(publisher, message)``
                pairs, all or nothing; a ``ValueError`` (an ``InterfaceError`` from the conversions for a
                non-finite or mis-shaped output, or an algorithm's own input check) is counted in
                ``invalid_outputs``, warned about, and nothing is published.
            build_diagnostics: Builds the diagnostic pairs (internals); published after the outputs, and
                only while one of their topics has a subscriber (a recorder, a plot): unobserved
                diagnostics cost nothing. A conversion error there is counted and warned about the same
                way.

        Returns:
            True when the control-chain outputs were published.
        """
        started = time.perf_counter()
        self.admission.mark_answered(stamp_ns)
        outputs = self._built(stamp_ns, build_outputs)
        self._last_answer = () if outputs is None else outputs
        if outputs is None:
            return False
        for publisher, message in outputs:
            publisher.publish(message)
        if time.perf_counter() - started > self.control_period:
            self.counters.deadline_misses += 1
        if build_diagnostics is not None and self._diagnostics_observed():
            diagnostics = self._built(stamp_ns, build_diagnostics)
            if diagnostics is not None and self._diagnostic_publishers is None:
                self._diagnostic_publishers = tuple(publisher for publisher, _ in diagnostics)
            for publisher, message in diagnostics or ():
                publisher.publish(message)
        return True

    def _diagnostics_observed(self) -> bool:
        """True when a diagnostics topic has a subscriber (or before the first diagnostics were built)."""
        if self._diagnostic_publishers is None:
            return True
        return any(publisher.get_subscription_count() > 0 for publisher in self._diagnostic_publishers)

    def _built(self, stamp_ns: int, build: Callable[[], Sequence[Output]]) -> tuple[Output, ...] | None:
        try:
            return tuple(build())
        except ValueError as error:  # InterfaceError from a conversion, or an algorithm's input check
            self.step_failed(stamp_ns, error)
            return None

    def step_failed(self, stamp_ns: int, error: Exception) -> None:
        """Count and warn about a step whose result cannot be published (nothing is published)."""
        self._refused("invalid_outputs", OUTPUTS_TOPIC, output_failure_text(stamp_ns, error))

    def counter_rows(self) -> Mapping[str, npt.NDArray[np.float64]]:
        """The node counters as internals rows (see :meth:`InputCounters.rows`)."""
        return self.counters.rows()

    # ------------------------------------------------------------------------------------ /diagnostics

    def health_counts(self) -> dict[str, int]:
        """Counts judged per diagnostics period: inputs, answered, the counters (subclasses add theirs)."""
        return {"inputs": self.inputs, "answered": self.answered, **self.counters.counts()}

    def health_warnings(self) -> tuple[str, ...]:
        """Names of :meth:`health_counts` whose increase makes the status WARN (subclasses add theirs)."""
        return WARN_COUNTERS

    def _period_counts(self) -> dict[str, int]:
        return self.health_counts()

    def _end_period(self) -> None:
        self._window.roll(self._period_counts())

    def health(self) -> Health:
        """The node's status by the thresholds of ``docs/NODES.md`` (OK / WARN / ERROR)."""
        now = self._period_counts()
        last, current = self._window.last, self._window.since(now)
        rate = self._window.rate("answered")
        findings: list[tuple[Level, str]] = []
        if last.get("inputs", 0) > 0 and last.get("answered", 0) == 0:
            findings.append((Level.ERROR, "no input answered during the last period: control stopped"))
        if last.get("invalid_outputs", 0) + current.get("invalid_outputs", 0) > 0:
            findings.append((Level.ERROR, "steps gave no valid output"))
        for name in self.health_warnings():
            count = last.get(name, 0) + current.get(name, 0)
            if count > 0:
                findings.append((Level.WARN, f"{name}: {count} in the last period"))
        steps = last.get("answered", 0)
        if steps and last.get("deadline_misses", 0) > DEADLINE_MISS_WARN_FRACTION * steps:
            findings.append((Level.WARN, f"{last['deadline_misses']} of {steps} steps missed the period"))
        values: dict[str, object] = {"loop_rate_hz": f"{rate:.1f}", **now, "last_error": self.last_error}
        fine = "answering measurements" if self.answered else "waiting for measurements"
        return worst(findings, fine, values)
