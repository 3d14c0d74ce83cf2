"""The experiments inside one recording: armed stretches cut where the scenario, the law or the gains change.

A segment: consecutive joined steps with both valves enabled (``hw_bridge_internals``; a bag without it is
armed throughout), no parameter event of the chain's nodes or ``reference_node``, no gap over
:data:`GAP_PERIODS` control periods; shorter than :data:`MIN_SEGMENT_NS`: left out and counted. Each
segment is a window of bag time, so analysed alone it is that window (docs/BAGS.md, "Windows and segments").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore
from smm_bag.errors import CorruptBagError
from smm_bag.reader import BagReader

from smm_analysis.runs.rerun import CHAIN_NODES
from smm_analysis.runs.stream import StepStream
from smm_analysis.runs.window import TimeBound, TimeWindow

__all__ = [
    "GAP_PERIODS",
    "MIN_SEGMENT_NS",
    "Segment",
    "SegmentSearch",
    "find_segments",
    "parameter_values",
]

MIN_SEGMENT_NS = 1_000_000_000
"""Shortest segment reported (ns of stamps, first to last step)."""
GAP_PERIODS = 100
"""A gap between steps of more than this many control periods starts a new segment."""
PARAMETER_EVENTS = "/parameter_events"
WATCHED_NODES = (*CHAIN_NODES, "reference_node")
"""Nodes whose parameter changes start a new experiment (gains, law, scenario)."""
_IGNORED_PARAMETERS = frozenset({"use_sim_time"})
_ENABLED = "hw_bridge.enabled"


@dataclass(frozen=True)
class Segment:
    """One experiment: steps with ``start_ns <= stamp < end_ns`` (``end_ns`` None: to the end).

    Attributes:
        number: 1-based, in time order.
        start_ns: First step's stamp (ns).
        end_ns: First stamp after the segment (ns), or None for the bag's end.
        last_ns: Last step's stamp (ns).
        steps: Steps in it.
        reason: Why it starts (``"start of the bag"``, ``"armed"``, a parameter change, a gap).
    """

    number: int
    start_ns: int
    end_ns: int | None
    last_ns: int
    steps: int
    reason: str

    @property
    def window(self) -> TimeWindow:
        """The segment as a window of bag time."""
        end = None if self.end_ns is None else TimeBound(self.end_ns, True)
        return TimeWindow(TimeBound(self.start_ns, True), end)


@dataclass
class SegmentSearch:
    """Segments found, and what was left out: short segments and disarmed steps."""

    segments: list[Segment] = field(default_factory=list)
    short_segments: int = 0
    disarmed_steps: int = 0


@dataclass(frozen=True)
class _Change:
    stamp_ns: int
    reason: str


def _events(path: Path | str) -> list[tuple[int, str, list[Any]]]:
    """``(stamp ns, node name, [rcl_interfaces/msg/Parameter])`` of each parameter event, new and changed.

    Raises:
        CorruptBagError: An event that does not decode as ``rcl_interfaces/msg/ParameterEvent``.
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    events = []
    with BagReader(Path(path)) as reader:
        if PARAMETER_EVENTS not in reader.topics:
            return []
        for message in reader.messages([PARAMETER_EVENTS]):
            event: Any
            try:
                event = store.deserialize_cdr(message.data, "rcl_interfaces/msg/ParameterEvent")
            except Exception as error:  # rosbags raises several kinds for bad CDR
                raise CorruptBagError(
                    f"{path}: a {PARAMETER_EVENTS} message does not decode ({error})"
                ) from None
            node = str(event.node).rstrip("/").split("/")[-1]
            stamp = int(event.stamp.sec) * 1_000_000_000 + int(event.stamp.nanosec)
            events.append((stamp, node, [*event.new_parameters, *event.changed_parameters]))
    return sorted(events, key=lambda event: event[0])


def parameter_changes(path: Path | str) -> list[_Change]:
    """Parameter events of :data:`WATCHED_NODES` with new or changed parameters, in stamp order.

    Raises:
        CorruptBagError: An event that does not decode as ``rcl_interfaces/msg/ParameterEvent``.
    """
    changes = []
    for stamp, node, parameters in _events(path):
        names = [str(p.name) for p in parameters if str(p.name) not in _IGNORED_PARAMETERS]
        if node in WATCHED_NODES and names:
            changes.append(_Change(stamp, f"{node}: {', '.join(sorted(names))} changed"))
    return changes


_VALUE_FIELDS = {
    1: "bool_value",
    2: "integer_value",
    3: "double_value",
    4: "string_value",
    6: "bool_array_value",
    7: "integer_array_value",
    8: "double_array_value",
    9: "string_array_value",
}
"""``rcl_interfaces/msg/ParameterValue`` type codes and their fields (5, byte arrays: no gain is one)."""


def parameter_values(path: Path | str, node: str, until_ns: int) -> dict[str, Any]:
    """Values ``/parameter_events`` set on ``node`` (its name) at stamps <= ``until_ns`` (the last of each).

    Raises:
        CorruptBagError: An event that does not decode as ``rcl_interfaces/msg/ParameterEvent``.
    """
    values: dict[str, Any] = {}
    for stamp, name, parameters in _events(path):
        if stamp > until_ns or name != node:
            continue
        for parameter in parameters:
            field_name = _VALUE_FIELDS.get(int(parameter.value.type))
            if field_name is None:
                continue
            value = getattr(parameter.value, field_name)
            values[str(parameter.name)] = value.tolist() if isinstance(value, np.ndarray) else value
    return values


def find_segments(path: Path | str, *, progress: Callable[[int, int], None] | None = None) -> SegmentSearch:
    """The segments of a bag (one pass over its steps; bounded memory).

    Raises:
        BagError: See :class:`StepStream`.
    """
    changes = parameter_changes(path)
    stream = StepStream(path, progress=progress)
    gap = GAP_PERIODS * stream.manifest.control_period_ns
    search = SegmentSearch()
    current: dict[str, int | str] | None = None
    previous_ns: int | None = None
    pending = 0  # index into changes

    def close(end_ns: int | None) -> None:
        nonlocal current
        if current is None:
            return
        start, last, steps = int(current["start"]), int(current["last"]), int(current["steps"])
        if last - start < MIN_SEGMENT_NS:
            search.short_segments += 1
        else:
            number = len(search.segments) + 1
            search.segments.append(Segment(number, start, end_ns, last, steps, str(current["reason"])))
        current = None

    for block in stream.blocks():
        enabled = block.internals.get(_ENABLED)
        armed = (
            np.ones(block.t_ns.size, dtype=bool)
            if enabled is None
            else np.all(np.isnan(enabled) | (enabled > 0.5), axis=1)
        )
        for stamp, is_armed in zip(block.t_ns.tolist(), armed.tolist(), strict=True):
            reason = None
            while pending < len(changes) and changes[pending].stamp_ns <= stamp:
                reason = changes[pending].reason
                pending += 1
            if not is_armed:
                close(stamp)
                search.disarmed_steps += 1
                previous_ns = stamp
                continue
            if current is not None and previous_ns is not None and stamp - previous_ns > gap:
                close(stamp)
                reason = reason or f"a gap of {(stamp - previous_ns) / 1e9:g} s"
            elif current is not None and reason is not None:
                close(stamp)
            if current is None:
                first = previous_ns is None
                current = {
                    "start": stamp,
                    "last": stamp,
                    "steps": 0,
                    "reason": "start of the bag" if first else (reason or "armed"),
                }
            current["last"] = stamp
            current["steps"] = int(current["steps"]) + 1
            previous_ns = stamp
    close(None)
    return search
