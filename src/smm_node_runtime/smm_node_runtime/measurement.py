"""Nodes that answer stamped measurements: the stamp gate, the drop counters and their base class.

The stamp policy (new, re-transmission, stale, ahead, future, time jump, invalid) and the status
thresholds are described in ``docs/NODES.md``.
"""

from __future__ import annotations

import enum
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Final, Unpack

import numpy as np
import numpy.typing as npt
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.publisher import Publisher

from smm_node_runtime.diagnostics import CountWindows, DiagnosticsPublisher, Health, Level, worst
from smm_node_runtime.node import NodeOptions, SmmNode
from smm_node_runtime.parameters import ConfigParameters, bounds, check_bounds

__all__ = [
    "COUNTER_ROWS",
    "DEFAULT_CONTROL_PERIOD",
    "REFUSED",
    "STAMP_PREFIX",
    "WARN_COUNTERS",
    "WARN_THROTTLE_S",
    "Admission",
    "ControlPeriodConfig",
    "InputCounters",
    "MeasurementDrivenNode",
    "Output",
    "StampGate",
    "StampPolicy",
    "values_of",
]

STAMP_PREFIX: Final[str] = "stamp"
"""Parameters of :class:`StampPolicy` are ``stamp.<field>``."""

WARN_THROTTLE_S: Final[float] = 1.0
"""At most one warning per input topic and per this many seconds (s); the counters count every drop."""

Output = tuple[Publisher, Any]
"""A message ready to go: ``(publisher, message)``."""


DEFAULT_CONTROL_PERIOD: Final[float] = 1e-3
"""Default control period (s): 1 kHz, the paper's."""

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


@dataclass(frozen=True)
class StampPolicy:
    """How far a stamp may jump before it is refused, and when a jump is believed (``docs/NODES.md``).

    Attributes:
        max_ahead_periods: A stamp more than this many control periods ahead of the last answered one is
            refused (dropped_ahead), an integer in [1, 100000].
        clock_tolerance: A stamp more than this many seconds ahead of the node's clock (ROS time: sim time
            with use_sim_time) is refused (dropped_future), in [0.001, 3600] s; not checked while the
            clock reads 0 (sim time before the first /clock).
        resync_samples: After this many consecutive refused stamps that follow each other (each at or after
            the previous one, within max_ahead_periods), with no acceptable stamp in between, the node takes
            them for a genuine time jump and resynchronises, an integer in [2, 1000].
    """

    max_ahead_periods: int = field(default=100, metadata=bounds(1, 100_000))
    clock_tolerance: float = field(default=1.0, metadata=bounds(1e-3, 3600.0))
    resync_samples: int = field(default=5, metadata=bounds(2, 1000))

    def __post_init__(self) -> None:
        check_bounds(self)


class Admission(enum.Enum):
    """What to do with an incoming stamp, relative to the last answered stamp and the node's clock."""

    NEW = "new"
    """Newer than the last answered, within ``max_ahead_periods``: process it."""
    RESYNC = "resync"
    """Accepted after a time jump (the last answered mark was forgotten): process it, warn."""
    DUPLICATE = "duplicate"
    """Equal to the last answered: a re-transmission."""
    STALE = "stale"
    """Older than the last answered: refused."""
    AHEAD = "ahead"
    """More than ``max_ahead_periods`` ahead of the last answered: refused."""
    FUTURE = "future"
    """More than ``clock_tolerance`` ahead of the node's clock: refused, never a resynchronisation."""


REFUSED: Final[frozenset[Admission]] = frozenset({Admission.STALE, Admission.AHEAD, Admission.FUTURE})
"""Admissions whose input is dropped and counted."""


class StampGate:
    """Remember the last answered stamp and classify incoming ones (pure, no ROS; ``docs/NODES.md``).

    A refused stamp never moves the last answered mark. Refused stamps that form a consistent track of their
    own (non-decreasing, steps of at most ``max_ahead_periods``), ``resync_samples`` in a row with no
    acceptable stamp in between, are a time jump: the gate forgets the mark and answers RESYNC.

    Args:
        policy: The limits (default :class:`StampPolicy`).
        control_period: Control period (s), the unit of ``max_ahead_periods``.
    """

    def __init__(
        self, policy: StampPolicy | None = None, control_period: float = DEFAULT_CONTROL_PERIOD
    ) -> None:
        self.policy = policy if policy is not None else StampPolicy()
        self.control_period = control_period
        self._last_stamp_ns: int | None = None
        self._track_ns: int | None = None
        self._track_length = 0
        self.last_jump: tuple[int, int] | None = None
        """``(old mark, new stamp)`` (ns) of the last resynchronisation, None before any."""

    @property
    def last_stamp_ns(self) -> int | None:
        """Stamp of the last answered measurement (ns), None before the first."""
        return self._last_stamp_ns

    @property
    def max_ahead_ns(self) -> int:
        """Largest accepted distance ahead of the last answered stamp (ns)."""
        return self.policy.max_ahead_periods * round(self.control_period * _NS_PER_S)

    def classify(self, stamp_ns: int, now_ns: int | None = None) -> Admission:
        """Classify ``stamp_ns`` (ns) given the node's clock ``now_ns`` (ns; None or 0: not checked).

        Refused stamps advance the jump detection; RESYNC has already forgotten the last answered mark.
        """
        policy = self.policy
        if now_ns and stamp_ns > now_ns + round(policy.clock_tolerance * _NS_PER_S):
            return Admission.FUTURE
        last = self._last_stamp_ns
        if last is None:
            return Admission.NEW
        if stamp_ns == last:
            return Admission.DUPLICATE
        window = self.max_ahead_ns
        if last < stamp_ns <= last + window:
            self._track_ns, self._track_length = None, 0
            return Admission.NEW
        track = self._track_ns
        follows = track is not None and track <= stamp_ns <= track + window
        self._track_length = self._track_length + 1 if follows else 1
        self._track_ns = stamp_ns
        if self._track_length >= policy.resync_samples:
            self.last_jump = (last, stamp_ns)
            self._last_stamp_ns = None
            self._track_ns, self._track_length = None, 0
            return Admission.RESYNC
        return Admission.STALE if stamp_ns < last else Admission.AHEAD

    def mark_answered(self, stamp_ns: int) -> None:
        """Record ``stamp_ns`` (ns) as answered.

        Raises:
            ValueError: ``stamp_ns`` is not newer than the last answered stamp.
        """
        if self._last_stamp_ns is not None and stamp_ns <= self._last_stamp_ns:
            raise ValueError(
                f"stamp {stamp_ns} ns is not newer than the last answered {self._last_stamp_ns} ns"
            )
        self._last_stamp_ns = stamp_ns

    def reset(self) -> None:
        """Forget the last answered stamp and any jump in progress (every stamp is NEW again)."""
        self._last_stamp_ns = None
        self._track_ns, self._track_length = None, 0


COUNTER_ROWS: Final[tuple[str, ...]] = (
    "dropped_invalid",
    "dropped_stale",
    "dropped_unmatched",
    "duplicates_answered",
    "invalid_outputs",
    "dropped_ahead",
    "dropped_future",
    "dropped_implausible",
    "conflicting_duplicates",
    "time_jumps",
    "deadline_misses",
)
"""Internals rows of the node counters (same count in both columns)."""

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


@dataclass
class InputCounters:
    """Counts of what a node did not process normally, since start.

    Attributes:
        dropped_invalid: Inputs breaking the interface contract (NaN/Inf, length, joint, layout, stamp).
        dropped_stale: Inputs older than the last answered stamp.
        dropped_unmatched: Stamps dropped by the synchroniser before all inputs for them arrived.
        duplicates_answered: Re-transmitted inputs answered by re-publishing the last answer.
        invalid_outputs: Steps whose output broke the contract (e.g. non-finite) and was not published.
        dropped_ahead: Inputs more than ``stamp.max_ahead_periods`` ahead of the last answered stamp.
        dropped_future: Inputs more than ``stamp.clock_tolerance`` ahead of the node's clock.
        dropped_implausible: Measurements outside the plausible range or step of the joints.
        conflicting_duplicates: Inputs with the last answered stamp but other values (not answered).
        time_jumps: Resynchronisations after a time jump.
        deadline_misses: Steps that took longer than the control period (wall clock).
    """

    dropped_invalid: int = 0
    dropped_stale: int = 0
    dropped_unmatched: int = 0
    duplicates_answered: int = 0
    invalid_outputs: int = 0
    dropped_ahead: int = 0
    dropped_future: int = 0
    dropped_implausible: int = 0
    conflicting_duplicates: int = 0
    time_jumps: int = 0
    deadline_misses: int = 0

    def rows(self) -> dict[str, npt.NDArray[np.float64]]:
        """Return ``{row name: [count, count]}`` in :data:`COUNTER_ROWS` order, for an internals message."""
        return {name: np.full(2, float(getattr(self, name))) for name in COUNTER_ROWS}

    def counts(self) -> dict[str, int]:
        """``{counter name: count}`` in :data:`COUNTER_ROWS` order."""
        return {name: int(getattr(self, name)) for name in COUNTER_ROWS}


_REFUSAL_COUNTERS: Final[Mapping[Admission, str]] = {
    Admission.STALE: "dropped_stale",
    Admission.AHEAD: "dropped_ahead",
    Admission.FUTURE: "dropped_future",
}
_REFUSAL_TEXT: Final[Mapping[Admission, str]] = {
    Admission.STALE: "older than the last answered",
    Admission.AHEAD: "too far ahead of the last answered",
    Admission.FUTURE: "ahead of the node's clock",
}


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
        self.counters = InputCounters()
        self.timing = ConfigParameters(self, "", ControlPeriodConfig(), read_only=True)
        self.stamp_policy = ConfigParameters(self, STAMP_PREFIX, StampPolicy(), on_change=self._on_policy)
        self._gate = StampGate(self.stamp_policy.config, self.timing.config.control_period)
        self._last_answer: tuple[Output, ...] = ()
        self._answered_values: dict[str, tuple[int, object]] = {}
        # Publishers the diagnostics went to, learnt from the first build: while none of them has a
        # subscriber, diagnostics are neither built nor published (lazy publishing, as image_transport
        # does), which is indistinguishable from publishing to nobody and halves the work per step.
        self._diagnostic_publishers: tuple[Publisher, ...] | None = None
        self._topic_loggers: dict[str, RcutilsLogger] = {}
        self.inputs = 0
        """Inputs received (every topic, valid or not)."""
        self.answered = 0
        """Stamps answered."""
        self.last_error = ""
        """The newest reason an input or output was dropped ("" before any)."""
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
        return self._gate.last_stamp_ns

    def _on_policy(self, policy: StampPolicy) -> None:
        self._gate.policy = policy

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
        setattr(self.counters, counter, getattr(self.counters, counter) + 1)
        self.last_error = message
        self.warn_throttled(topic, f"{message}; {getattr(self.counters, counter)} {counter} so far")
        self.diagnostics.check()

    def reject(self, topic: str, error: Exception) -> None:
        """Drop an input that broke the interface contract: count it and warn (throttled)."""
        self.inputs += 1
        self._refused(
            "dropped_invalid", topic, f"dropped input on '{topic}' ({type(error).__name__}: {error})"
        )

    def reject_implausible(self, topic: str, stamp_ns: int, reason: str) -> None:
        """Drop a measurement that is valid but physically implausible (after :meth:`admit` accepted it)."""
        self._refused(
            "dropped_implausible",
            topic,
            f"dropped implausible measurement on '{topic}' at {stamp_ns} ns: {reason}",
        )

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
        self.inputs += 1
        last = self._gate.last_stamp_ns
        admission = self._gate.classify(stamp_ns, self.get_clock().now().nanoseconds)
        if admission is Admission.NEW:
            self._answered_values[topic] = (stamp_ns, values)
            return True
        if admission is Admission.RESYNC:
            self.counters.time_jumps += 1
            self._answered_values.clear()
            self.last_error = f"time jump on '{topic}' from {last} ns to {stamp_ns} ns: resynchronised"
            self.get_logger().warning(  # type: ignore[no-untyped-call]
                f"{self.last_error} after {self._gate.policy.resync_samples} consistent samples"
            )
            self._answered_values[topic] = (stamp_ns, values)
            self.on_time_jump(backward=last is not None and stamp_ns < last)
            self.diagnostics.check()
            return True
        if admission is Admission.DUPLICATE:
            answered = self._answered_values.get(topic)
            if answered is not None and answered[0] == stamp_ns and answered[1] != values:
                self._refused(
                    "conflicting_duplicates",
                    topic,
                    f"dropped input on '{topic}': stamp {stamp_ns} ns was answered with other values",
                )
                return False
            self.counters.duplicates_answered += 1
            for publisher, message in self._last_answer:
                publisher.publish(message)
            return False
        self._refused(
            _REFUSAL_COUNTERS[admission],
            topic,
            f"dropped input on '{topic}': stamp {stamp_ns} ns is {_REFUSAL_TEXT[admission]} "
            f"(last answered {last} ns)",
        )
        return False

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
        self._gate.mark_answered(stamp_ns)
        self.answered += 1
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
        self._refused(
            "invalid_outputs",
            "~/outputs",
            f"no output for stamp {stamp_ns} ns ({type(error).__name__}: {error})",
        )

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
