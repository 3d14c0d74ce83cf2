"""Which inputs a node answers: the stamp policy's verdict on each, and the counts of what it dropped (pure).

:class:`InputAdmission` is what :class:`~smm_node_runtime.MeasurementDrivenNode` and the controller's pure
core share: the stamp gate, the counters and the last reason; the node only logs and publishes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final, NamedTuple

import numpy as np
import numpy.typing as npt

from smm_node_runtime.stamp_gate import Admission, StampGate, StampPolicy

__all__ = [
    "COUNTER_ROWS",
    "OUTPUTS_TOPIC",
    "InputAdmission",
    "InputCounters",
    "Verdict",
    "implausible_text",
    "output_failure_text",
]

OUTPUTS_TOPIC: Final[str] = "~/outputs"
"""The name refused outputs are warned about under."""


def output_failure_text(stamp_ns: int, error: Exception) -> str:
    """Why a step gave no output (the text of an ``invalid_outputs`` count)."""
    return f"no output for stamp {stamp_ns} ns ({type(error).__name__}: {error})"


def implausible_text(topic: str, stamp_ns: int, reason: str) -> str:
    """Why a measurement was dropped as implausible (the text of a ``dropped_implausible`` count)."""
    return f"dropped implausible measurement on '{topic}' at {stamp_ns} ns: {reason}"


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


class Verdict(NamedTuple):
    """What the stamp policy made of one input.

    Attributes:
        admission: The gate's class of the stamp.
        counter: The counter it was counted in when dropped (or ``duplicates_answered``), else None.
        message: Why ("" for a new stamp).
        backward: RESYNC only: the jump went to older stamps (a new run).
    """

    admission: Admission
    counter: str | None = None
    message: str = ""
    backward: bool = False

    @property
    def accepted(self) -> bool:
        """True when the input is to be processed (a new stamp, or the first after a time jump)."""
        return self.admission is Admission.NEW or self.admission is Admission.RESYNC

    @property
    def answer_again(self) -> bool:
        """True for a re-transmission to be answered with the last answer."""
        return self.counter == "duplicates_answered"


_NEW: Final[Verdict] = Verdict(Admission.NEW)


class InputAdmission:
    """The stamp gate, the counters and the last reason of one node (pure: times passed in).

    Args:
        policy: The stamp policy.
        control_period: Control period (s).
    """

    def __init__(self, policy: StampPolicy, control_period: float) -> None:
        self.gate = StampGate(policy, control_period)
        self.counters = InputCounters()
        self.inputs = 0
        """Inputs received (every topic, valid or not)."""
        self.answered = 0
        """Stamps answered."""
        self.last_error = ""
        """The newest reason an input or output was dropped ("" before any)."""
        self._answered_values: dict[str, tuple[int, object]] = {}

    def refuse(self, counter: str, message: str) -> None:
        """Counts a dropped input or output in ``counter`` and remembers why."""
        setattr(self.counters, counter, getattr(self.counters, counter) + 1)
        self.last_error = message

    def admit(self, topic: str, stamp_ns: int, values: object, now_ns: int) -> Verdict:
        """The verdict on an input stamped ``stamp_ns`` (ns) on ``topic``; ``now_ns``: the node's clock.

        ``values``: the input's values in a comparable form, or None; a duplicate stamp is answered only
        when its values equal those answered for that stamp.
        """
        self.inputs += 1
        last = self.gate.last_stamp_ns
        admission = self.gate.classify(stamp_ns, now_ns)
        if admission is Admission.NEW:
            self._answered_values[topic] = (stamp_ns, values)
            return _NEW
        if admission is Admission.RESYNC:
            self.counters.time_jumps += 1
            self._answered_values.clear()
            self.last_error = f"time jump on '{topic}' from {last} ns to {stamp_ns} ns: resynchronised"
            self._answered_values[topic] = (stamp_ns, values)
            backward = last is not None and stamp_ns < last
            return Verdict(Admission.RESYNC, "time_jumps", self.last_error, backward)
        if admission is Admission.DUPLICATE:
            answered = self._answered_values.get(topic)
            if answered is not None and answered[0] == stamp_ns and answered[1] != values:
                message = f"dropped input on '{topic}': stamp {stamp_ns} ns was answered with other values"
                self.refuse("conflicting_duplicates", message)
                return Verdict(Admission.DUPLICATE, "conflicting_duplicates", message)
            self.counters.duplicates_answered += 1
            return Verdict(Admission.DUPLICATE, "duplicates_answered")
        counter = _REFUSAL_COUNTERS[admission]
        message = (
            f"dropped input on '{topic}': stamp {stamp_ns} ns is {_REFUSAL_TEXT[admission]} "
            f"(last answered {last} ns)"
        )
        self.refuse(counter, message)
        return Verdict(admission, counter, message)

    def mark_answered(self, stamp_ns: int) -> None:
        """Records ``stamp_ns`` (ns) as answered (a re-transmission of it is then a duplicate)."""
        self.gate.mark_answered(stamp_ns)
        self.answered += 1
