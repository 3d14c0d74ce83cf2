"""Nodes that answer stamped measurements: the stamp gate, the drop counters and their base class.

The stamp policy (new, re-transmission, stale, invalid) is described in ``docs/NODES.md``.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final, Unpack

import numpy as np
import numpy.typing as npt
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.publisher import Publisher

from smm_node_runtime.node import NodeOptions, SmmNode

__all__ = [
    "COUNTER_ROWS",
    "DEFAULT_CONTROL_PERIOD",
    "WARN_THROTTLE_S",
    "Admission",
    "ControlPeriodConfig",
    "InputCounters",
    "MeasurementDrivenNode",
    "Output",
    "StampGate",
]

WARN_THROTTLE_S: Final[float] = 1.0
"""At most one warning per input topic and per this many seconds (s); the counters count every drop."""

Output = tuple[Publisher, Any]
"""A message ready to go: ``(publisher, message)``."""



DEFAULT_CONTROL_PERIOD: Final[float] = 1e-3
"""Default control period (s): 1 kHz, the paper's."""


@dataclass(frozen=True)
class ControlPeriodConfig:
    """The step size a node integrates its algorithm with (declared read-only: fixed at start-up).

    Attributes:
        control_period: Control period dt (s), > 0 and finite; must equal the plant's period (the
            simulator's ``control_period``), because nodes step once per measurement with this dt.
    """

    control_period: float = DEFAULT_CONTROL_PERIOD

    def __post_init__(self) -> None:
        value = self.control_period
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value < float("inf"):
            raise ValueError(f"control_period must be a finite number of seconds > 0, got {value!r}")




class Admission(enum.Enum):
    """What to do with an incoming stamp, relative to the last answered stamp."""

    NEW = "new"
    DUPLICATE = "duplicate"
    STALE = "stale"


class StampGate:
    """Remember the last answered stamp and classify incoming ones (pure, no ROS)."""

    def __init__(self) -> None:
        self._last_stamp_ns: int | None = None

    @property
    def last_stamp_ns(self) -> int | None:
        """Stamp of the last answered measurement (ns), None before the first."""
        return self._last_stamp_ns

    def classify(self, stamp_ns: int) -> Admission:
        """Classify ``stamp_ns`` (ns): NEW if newer than the last answered, DUPLICATE if equal, else STALE."""
        last = self._last_stamp_ns
        if last is None or stamp_ns > last:
            return Admission.NEW
        return Admission.DUPLICATE if stamp_ns == last else Admission.STALE

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
        """Forget the last answered stamp (every stamp is NEW again)."""
        self._last_stamp_ns = None


COUNTER_ROWS: Final[tuple[str, ...]] = (
    "dropped_invalid",
    "dropped_stale",
    "dropped_unmatched",
    "duplicates_answered",
    "invalid_outputs",
)
"""Internals rows of the node counters (same count in both columns)."""


@dataclass
class InputCounters:
    """Counts of what a node did not process normally, since start.

    Attributes:
        dropped_invalid: Inputs breaking the interface contract (NaN/Inf, length, joint, layout, stamp).
        dropped_stale: Inputs older than the last answered stamp.
        dropped_unmatched: Stamps dropped by the synchroniser before all inputs for them arrived.
        duplicates_answered: Re-transmitted inputs answered by re-publishing the last answer.
        invalid_outputs: Steps whose output broke the contract (e.g. non-finite) and was not published.
    """

    dropped_invalid: int = 0
    dropped_stale: int = 0
    dropped_unmatched: int = 0
    duplicates_answered: int = 0
    invalid_outputs: int = 0

    def rows(self) -> dict[str, npt.NDArray[np.float64]]:
        """Return ``{row name: [count, count]}`` in :data:`COUNTER_ROWS` order, for an internals message."""
        return {name: np.full(2, float(getattr(self, name))) for name in COUNTER_ROWS}


class MeasurementDrivenNode(SmmNode):
    """Base class of a node that answers stamped measurements (policy: ``docs/NODES.md``).

    Subclasses: parse each input with the ``smm_msgs_py`` conversions inside ``try: ... except
    InterfaceError as error: self.reject(topic, error)``; call :meth:`admit` with the stamp and return
    unless it is True; when the step for a stamp is done, build the output messages and hand them to
    :meth:`answer` (a conversion error there is counted as an invalid output and nothing is published).
    """

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        self.counters = InputCounters()
        self._gate = StampGate()
        self._last_answer: tuple[Output, ...] = ()
        # Publishers the diagnostics went to, learnt from the first build: while none of them has a
        # subscriber, diagnostics are neither built nor published (lazy publishing, as image_transport
        # does), which is indistinguishable from publishing to nobody and halves the work per step.
        self._diagnostic_publishers: tuple[Publisher, ...] | None = None
        self._topic_loggers: dict[str, RcutilsLogger] = {}

    @property
    def last_answered_stamp_ns(self) -> int | None:
        """Stamp (ns) of the last measurement this node answered, None before the first."""
        return self._gate.last_stamp_ns

    def warn_throttled(self, topic: str, message: str) -> None:
        """Log a warning, at most once per :data:`WARN_THROTTLE_S` per ``topic`` (throttled per topic)."""
        logger = self._topic_loggers.get(topic)
        if logger is None:
            child_name = topic.strip("~/").replace("/", ".")
            logger = self.get_logger().get_child(child_name)  # type: ignore[no-untyped-call]
            self._topic_loggers[topic] = logger
        logger.warning(message, throttle_duration_sec=WARN_THROTTLE_S)

    def reject(self, topic: str, error: Exception) -> None:
        """Drop an input that broke the interface contract: count it and warn (throttled)."""
        self.counters.dropped_invalid += 1
        self.warn_throttled(
            topic,
            f"dropped input on '{topic}' ({type(error).__name__}: {error}); "
            f"{self.counters.dropped_invalid} invalid inputs so far",
        )

    def admit(self, topic: str, stamp_ns: int) -> bool:
        """Apply the stamp policy to an input stamped ``stamp_ns`` (ns) on ``topic``.

        Returns:
            True when the stamp is new (the caller processes the input). False for a duplicate (the last
            answer has been re-published) or a stale stamp (counted and warned about).
        """
        admission = self._gate.classify(stamp_ns)
        if admission is Admission.NEW:
            return True
        if admission is Admission.DUPLICATE:
            self.counters.duplicates_answered += 1
            for publisher, message in self._last_answer:
                publisher.publish(message)
            return False
        self.counters.dropped_stale += 1
        self.warn_throttled(
            topic,
            f"dropped stale input on '{topic}': stamp {stamp_ns} ns is older than the last answered "
            f"{self._gate.last_stamp_ns} ns; {self.counters.dropped_stale} stale inputs so far",
        )
        return False

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
        self._gate.mark_answered(stamp_ns)
        outputs = self._built(stamp_ns, build_outputs)
        self._last_answer = () if outputs is None else outputs
        if outputs is None:
            return False
        for publisher, message in outputs:
            publisher.publish(message)
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
        self.counters.invalid_outputs += 1
        self.warn_throttled(
            "~/outputs",
            f"no output for stamp {stamp_ns} ns ({type(error).__name__}: {error}); "
            f"{self.counters.invalid_outputs} invalid outputs so far",
        )

    def counter_rows(self) -> Mapping[str, npt.NDArray[np.float64]]:
        """The node counters as internals rows (see :meth:`InputCounters.rows`)."""
        return self.counters.rows()
