"""The stack's topics of a bag joined on stamps while reading, handed on in blocks of a fixed number of steps.

Memory is bounded: each topic's samples wait in a reorder window (:data:`REORDER_WINDOW_NS` behind the
newest stamp read); a message already behind it is counted per topic and left out, as is one stamped more
than :data:`AHEAD_LIMIT_NS` after its log time (beyond the bag's :func:`clock_offset`). Blocks of
:data:`BLOCK_STEPS` steps are cut by step number, so nothing depends on the writer's chunking
(docs/BAGS.md, "Streaming analysis").
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from smm_bag.bulk import decode_arrays, decode_joint_states
from smm_bag.cdr import stamp_of
from smm_bag.errors import CorruptBagError, MissingTopicsError
from smm_bag.manifest import RunManifest
from smm_bag.reader import BagReader

from smm_analysis.runs.window import TimeWindow

__all__ = [
    "AHEAD_LIMIT_NS",
    "BLOCK_STEPS",
    "REORDER_WINDOW_NS",
    "JoinReport",
    "StepBlock",
    "StepStream",
    "clock_offset",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
REORDER_WINDOW_NS = 1_000_000_000
"""How far (ns of stamps) a message may arrive behind the newest stamp read and still be joined."""
AHEAD_LIMIT_NS = 60_000_000_000
"""A message stamped more than this after its log time (ns), beyond the bag's clock offset, is left out and
counted: the preflight's rehearsal (stamped an hour ahead, docs/LAUNCH.md) or a clock gone wrong, never a step
of the run."""
OFFSET_SCAN_NS = 120_000_000_000
"""How much of a bag's start (ns of log time) :func:`clock_offset` reads: past any rehearsal (<= 30 s)."""
BLOCK_STEPS = 8192
"""Steps per block handed on (the unit of the ordered sums, docs/BAGS.md)."""
READ_BATCH = 32_768
"""Messages decoded at once."""
JOINTS = ("alpha", "beta")
_REFERENCE_ROWS = ("position", "velocity", "acceleration")
_INTERNAL = "internal:"


@dataclass(frozen=True, eq=False)
class StepBlock:
    """Consecutive joined steps; optional quantities are NaN at steps where they were not recorded.

    Attributes:
        first_step: Number of the block's first step in the run (0-based).
        t_ns: Stamps (ns), strictly increasing, shape (n,).
        reference: q_d, q_d', q_d'' (rad, rad/s, rad/s^2), shape (n, 3, 2).
        position: Position the errors are measured on (rad), shape (n, 2).
        measured_position: Encoder position (rad), shape (n, 2).
        command_torque: ``torque_command`` (N m), shape (n, 2).
        applied_torque: ``joint_states`` effort (N m), shape (n, 2).
        disturbance_estimate: xi~ (N m), shape (n, 2).
        internals: Rows of ``controller_internals`` / ``observer_state`` by quantity, and of
            ``hw_bridge_internals`` as ``hw_bridge.<quantity>``, each (n, 2).
        latency_ns: Command receive time minus measurement receive time (ns), shape (n,).
    """

    first_step: int
    t_ns: IntArray
    reference: FloatArray
    position: FloatArray
    measured_position: FloatArray
    command_torque: FloatArray
    applied_torque: FloatArray
    disturbance_estimate: FloatArray
    internals: Mapping[str, FloatArray]
    latency_ns: IntArray

    @property
    def desired_position(self) -> FloatArray:
        """q_d (rad), shape (n, 2)."""
        return self.reference[:, 0, :]


@dataclass
class JoinReport:
    """What the join saw: steps passed on, steps left out, messages that came too late (per topic)."""

    steps: int = 0
    incomplete_steps: int = 0
    late_messages: dict[str, int] = field(default_factory=dict)
    ahead_messages: dict[str, int] = field(default_factory=dict)
    first_ns: int | None = None
    last_ns: int | None = None
    messages_read: int = 0


@dataclass
class _Part:
    stamps: IntArray
    values: FloatArray
    log_times: IntArray


def _dedupe(stamps: IntArray, values: FloatArray, log_times: IntArray) -> _Part:
    """Sorted by stamp; of equal stamps the last received (last in the input) is kept."""
    order = np.argsort(stamps, kind="stable")
    stamps, values, log_times = stamps[order], values[order], log_times[order]
    last = np.ones(stamps.size, dtype=bool)
    last[:-1] = stamps[1:] != stamps[:-1]
    return _Part(stamps[last], values[last], log_times[last])


def _items(labels: tuple[str, ...], dimension: str) -> tuple[str, ...] | None:
    prefix = dimension + ":"
    for label in labels:
        if label.startswith(prefix):
            return tuple(label[len(prefix) :].split(","))
    return None


def _joint_order(names: tuple[str, ...], topic: str) -> tuple[int, int]:
    try:
        return names.index("alpha"), names.index("beta")
    except ValueError:
        raise CorruptBagError(f"{topic}: JointState names {list(names)} lack alpha or beta") from None


def _joint_parts(topic: str, buffers: list[bytes], log_times: IntArray, field_name: str) -> _Part | None:
    """One JointState field (position or effort) of a batch; None when no message has it."""
    count = len(buffers)
    stamps = np.empty(count, dtype=np.int64)
    values = np.full((count, 2), np.nan)
    present = np.zeros(count, dtype=bool)
    for indices, columns in decode_joint_states(buffers):
        order = _joint_order(columns.names, topic)
        source = getattr(columns, field_name)
        stamps[indices] = columns.stamps
        if source is None or source.shape[1] == 0:
            continue
        if source.shape[1] <= max(order):
            raise CorruptBagError(
                f"{topic}: JointState {field_name} has {source.shape[1]} values for 2 joints"
            )
        values[indices] = source[:, list(order)]
        present[indices] = True
    if not np.any(present):
        return None
    return _Part(stamps[present], values[present], log_times[present])


def _array_part(
    topic: str, buffers: list[bytes], log_times: IntArray, check: Callable[[tuple[str, ...], int], None]
) -> _Part:
    count = len(buffers)
    stamps = np.empty(count, dtype=np.int64)
    width: int | None = None
    values: FloatArray | None = None
    for indices, columns in decode_arrays(buffers):
        check(columns.labels, columns.data.shape[1])
        if values is None:
            width = columns.data.shape[1]
            values = np.empty((count, width))
        if columns.data.shape[1] != width:
            raise CorruptBagError(f"{topic}: messages of {width} and {columns.data.shape[1]} values")
        stamps[indices] = columns.stamps
        values[indices] = columns.data
    assert values is not None
    return _Part(stamps, values, log_times)


def _labelled_parts(topic: str, buffers: list[bytes], log_times: IntArray) -> dict[str, _Part]:
    rows: dict[str, tuple[list[IntArray], list[FloatArray], list[IntArray]]] = {}
    for indices, columns in decode_arrays(buffers):
        quantities = _items(columns.labels, "quantity")
        if _items(columns.labels, "joint") != JOINTS or quantities is None:
            raise CorruptBagError(
                f"{topic}: labelled array without quantity and joint (alpha, beta) dimensions"
            )
        if columns.data.shape[1] != 2 * len(quantities):
            raise CorruptBagError(f"{topic}: {columns.data.shape[1]} values for {len(quantities)} quantities")
        times = log_times[indices]
        for row, quantity in enumerate(quantities):
            entry = rows.setdefault(quantity, ([], [], []))
            entry[0].append(columns.stamps)
            entry[1].append(columns.data[:, 2 * row : 2 * row + 2])
            entry[2].append(times)
    return {
        quantity: _Part(np.concatenate(s), np.concatenate(v), np.concatenate(t))
        for quantity, (s, v, t) in rows.items()
    }


def clock_offset(reader: BagReader, topic: str) -> int:
    """Stamp minus log time (ns) of the run on ``topic`` (``joint_states``), at most 0.

    The smallest over the first :data:`OFFSET_SCAN_NS` of log time: a hardware bag's stamps are the board's
    time since its start, a simulator's the host's clock; a rehearsal stamped ahead is above it.
    """
    offset, first = 0, None
    for _, log_time, data in reader.raw_messages([topic]):
        first = log_time if first is None else first
        if log_time - first > OFFSET_SCAN_NS:
            break
        stamp = stamp_of("sensor_msgs/msg/JointState", data)
        if stamp is not None:
            offset = min(offset, stamp - log_time)
    return offset


class _Pending:
    """One series' samples not yet joined, in arrival order."""

    def __init__(self) -> None:
        self.parts: list[_Part] = []

    def add(self, part: _Part) -> None:
        self.parts.append(part)

    def take(self, watermark: int) -> _Part | None:
        """The samples with stamp <= watermark, deduplicated and sorted; the rest stay."""
        if not self.parts:
            return None
        stamps = np.concatenate([p.stamps for p in self.parts])
        values = np.concatenate([p.values for p in self.parts])
        times = np.concatenate([p.log_times for p in self.parts])
        ready = stamps <= watermark
        rest = ~ready
        self.parts = [_Part(stamps[rest], values[rest], times[rest])] if np.any(rest) else []
        if not np.any(ready):
            return None
        return _dedupe(stamps[ready], values[ready], times[ready])


class StepStream:
    """Reads a bag of the stack once, joining its topics on stamps; iterate :meth:`blocks`.

    Args:
        path: Bag folder or file.
        window: Steps to keep (default: all).
        progress: Called with (messages read, messages to read).
        reorder_window_ns: How far behind the newest stamp a message may arrive (ns).
        block_steps: Steps per block.
        read_batch: Messages decoded at once.

    Raises (from :meth:`blocks`):
        BagError: Not a bag, truncated or corrupt (see :class:`BagReader`).
        MissingTopicsError: No reference, torque command or measurement, or fewer than 2 complete steps.
        CorruptBagError: A message does not follow docs/INTERFACES.md.
    """

    def __init__(
        self,
        path: Path | str,
        *,
        window: TimeWindow | None = None,
        progress: Callable[[int, int], None] | None = None,
        reorder_window_ns: int = REORDER_WINDOW_NS,
        block_steps: int = BLOCK_STEPS,
        read_batch: int = READ_BATCH,
    ) -> None:
        if reorder_window_ns < 0 or block_steps < 2 or read_batch < 1:
            raise ValueError("reorder_window_ns must be >= 0, block_steps >= 2 and read_batch >= 1")
        self.bag = Path(path)
        self.window = window if window is not None else TimeWindow()
        self.progress = progress
        self.reorder_window_ns = reorder_window_ns
        self.block_steps = block_steps
        self.read_batch = read_batch
        self.report = JoinReport()
        with BagReader(self.bag) as reader:
            self.manifest = RunManifest.from_custom_data(reader.metadata.custom_data)
            counts = {topic.name: topic.message_count for topic in reader.metadata.topics}
            name = self.manifest.topic
            reader.require((name("joint_states"), name("reference"), name("torque_command")))
            self.offset_ns = clock_offset(reader, name("joint_states"))
            """The run's stamp minus log time (ns, :func:`clock_offset`)."""
        self.has_ground_truth = counts.get(name("ground_truth"), 0) > 0
        self.position_source = "ground truth" if self.has_ground_truth else "measured"

    @property
    def label(self) -> str:
        """Controller name from the manifest, else the bag folder's name."""
        return self.manifest.controller or self.bag.name

    def blocks(self) -> Iterator[StepBlock]:
        """The joined steps in blocks of ``block_steps`` (the last one fewer), in stamp order."""
        out = _Rebuffer(self.block_steps)
        for columns in self._joined():
            for block in out.add(columns):
                yield self._block(block)
        for block in out.flush():
            yield self._block(block)
        if self.report.steps < 2:
            raise MissingTopicsError(
                f"{self.bag}: fewer than 2 control steps have a measurement, a reference and a torque "
                "command "
                f"with the same stamp{'' if self.window.whole else ' in the window'} "
                f"({self.report.steps} found)"
            )

    def _block(self, columns: dict[str, np.ndarray]) -> StepBlock:
        first = self.report.steps
        size = int(columns["t_ns"].size)
        self.report.steps += size
        internals = {key[len(_INTERNAL) :]: v for key, v in columns.items() if key.startswith(_INTERNAL)}
        estimate = columns["estimate"]
        fallback = internals.get("disturbance_estimate")
        if fallback is not None and np.all(np.isnan(estimate)):
            estimate = fallback
        return StepBlock(
            first_step=first,
            t_ns=columns["t_ns"].astype(np.int64),
            reference=columns["reference"].reshape(size, 3, 2),
            position=columns["position"],
            measured_position=columns["measured"],
            command_torque=columns["command"],
            applied_torque=columns["applied"],
            disturbance_estimate=estimate,
            internals=internals,
            latency_ns=columns["latency"].astype(np.int64),
        )

    def _joined(self) -> Iterator[dict[str, np.ndarray]]:
        name = self.manifest.topic
        joint_states, ground_truth = name("joint_states"), name("ground_truth")
        reference_topic, command_topic = name("reference"), name("torque_command")
        estimate_topic = name("disturbance_estimate")
        hw_bridge = name("hw_bridge_internals")
        labelled = (name("controller_internals"), name("observer_state"), hw_bridge)

        def reference_layout(labels: tuple[str, ...], width: int) -> None:
            if _items(labels, "order") != _REFERENCE_ROWS or _items(labels, "joint") != JOINTS or width != 6:
                raise CorruptBagError(f"{reference_topic}: not a 3x2 reference (labels {labels})")

        def torque_layout(labels: tuple[str, ...], width: int) -> None:
            if _items(labels, "joint") != JOINTS or width != 2:
                raise CorruptBagError(f"{command_topic}: {width} values, expected 2 (labels {labels})")

        def estimate_layout(labels: tuple[str, ...], width: int) -> None:
            if _items(labels, "joint") != JOINTS or width < 2:
                raise CorruptBagError(f"{estimate_topic}: not a per-joint estimate (labels {labels})")

        pending: dict[str, _Pending] = {}
        topic_of: dict[str, str] = {}
        late, ahead = self.report.late_messages, self.report.ahead_messages
        required = ["measured", "reference", "command"] + (["truth"] if self.has_ground_truth else [])
        state = _JoinState(self.window)

        def add(series: str, topic: str, part: _Part | None, counted: bool = True) -> None:
            """``counted``: this series' left-out messages are counted (one series per message counts)."""
            if part is None or part.stamps.size == 0:
                return
            topic_of[series] = topic
            beyond = part.stamps - part.log_times - self.offset_ns > AHEAD_LIMIT_NS
            if np.any(beyond):
                if counted:
                    ahead[topic] = ahead.get(topic, 0) + int(np.count_nonzero(beyond))
                part = _Part(part.stamps[~beyond], part.values[~beyond], part.log_times[~beyond])
            if state.finalised is not None:
                early = part.stamps <= state.finalised
                if np.any(early):
                    if counted:
                        late[topic] = late.get(topic, 0) + int(np.count_nonzero(early))
                    keep = ~early
                    part = _Part(part.stamps[keep], part.values[keep], part.log_times[keep])
            if part.stamps.size:
                state.newest = max(state.newest, int(part.stamps.max()))
                pending.setdefault(series, _Pending()).add(part)

        def decode(topic: str, buffers: list[bytes], times: list[int]) -> None:
            log_times = np.array(times, dtype=np.int64)
            if topic == joint_states:
                measured = _joint_parts(topic, buffers, log_times, "position")
                add("measured", topic, measured)
                add("applied", topic, _joint_parts(topic, buffers, log_times, "effort"), measured is None)
            elif topic == ground_truth:
                add("truth", topic, _joint_parts(topic, buffers, log_times, "position"))
            elif topic == reference_topic:
                add("reference", topic, _array_part(topic, buffers, log_times, reference_layout))
            elif topic == command_topic:
                add("command", topic, _array_part(topic, buffers, log_times, torque_layout))
            elif topic == estimate_topic:
                part = _array_part(topic, buffers, log_times, estimate_layout)
                add("estimate", topic, _Part(part.stamps, part.values[:, :2], part.log_times))
            else:
                prefix = _INTERNAL + ("hw_bridge." if topic == hw_bridge else "")
                for number, (quantity, part) in enumerate(_labelled_parts(topic, buffers, log_times).items()):
                    add(prefix + quantity, topic, part, number == 0)

        with BagReader(self.bag) as reader:
            counts = {topic.name: topic.message_count for topic in reader.metadata.topics}
            wanted = [
                topic
                for topic in (
                    joint_states,
                    ground_truth,
                    reference_topic,
                    command_topic,
                    estimate_topic,
                    *labelled,
                )
                if counts.get(topic, 0) > 0
            ]
            total = sum(counts[topic] for topic in wanted)
            buffers: dict[str, list[bytes]] = {topic: [] for topic in wanted}
            times: dict[str, list[int]] = {topic: [] for topic in wanted}
            batched = 0
            for topic, log_time, data in reader.raw_messages(wanted):
                buffers[topic].append(data)
                times[topic].append(log_time)
                batched += 1
                if batched < self.read_batch:
                    continue
                self.report.messages_read += batched
                batched = 0
                for key in wanted:
                    if buffers[key]:
                        decode(key, buffers[key], times[key])
                        buffers[key], times[key] = [], []
                if self.progress is not None:
                    self.progress(self.report.messages_read, total)
                joined = state.finalise(pending, required, state.newest - self.reorder_window_ns, self.report)
                if joined is not None:
                    yield joined
                if state.past_end:
                    break
            else:
                self.report.messages_read += batched
                for key in wanted:
                    if buffers[key]:
                        decode(key, buffers[key], times[key])
                joined = state.finalise(pending, required, np.iinfo(np.int64).max, self.report)
                if joined is not None:
                    yield joined
            if self.progress is not None:
                self.progress(total if not state.past_end else self.report.messages_read, total)


class _JoinState:
    """Where the join stands: the newest stamp read, the stamp up to which steps are final, the window."""

    def __init__(self, window: TimeWindow) -> None:
        self.window = window
        self.newest = np.iinfo(np.int64).min
        self.finalised: int | None = None
        self.bounds: tuple[int | None, int | None] | None = None
        self.past_end = False
        self.unplaced_incomplete: list[IntArray] = []

    def finalise(
        self, pending: dict[str, _Pending], required: list[str], watermark: int, report: JoinReport
    ) -> dict[str, np.ndarray] | None:
        """Joins the pending steps with stamp <= watermark; returns their columns (None if none)."""
        if self.finalised is not None and watermark <= self.finalised:
            return None
        self.finalised = watermark
        ready = {series: part for series, p in pending.items() if (part := p.take(watermark)) is not None}
        if any(series not in ready for series in required):
            union = [ready[s].stamps for s in required if s in ready]
            if union:
                self._incomplete(np.unique(np.concatenate(union)), report)
            return None
        complete = ready[required[0]].stamps
        for series in required[1:]:
            complete = np.intersect1d(complete, ready[series].stamps, assume_unique=True)
        every = np.unique(np.concatenate([ready[s].stamps for s in required]))
        incomplete = np.setdiff1d(every, complete, assume_unique=True)
        if complete.size and self.bounds is None:
            self.bounds = self.window.resolve(int(complete[0]))
        self._incomplete(incomplete, report)
        complete = self._inside(complete)
        if complete.size == 0:
            return None
        if report.first_ns is None:
            report.first_ns = int(complete[0])
        report.last_ns = int(complete[-1])
        return _columns(complete, ready, "truth" if "truth" in required else "measured")

    def _inside(self, stamps: IntArray) -> IntArray:
        if self.bounds is None:
            return stamps
        start, end = self.bounds
        keep = np.ones(stamps.size, dtype=bool)
        if start is not None:
            keep &= stamps >= start
        if end is not None:
            beyond = stamps >= end
            if np.any(beyond):
                self.past_end = True
            keep &= ~beyond
        return stamps[keep]

    def _incomplete(self, stamps: IntArray, report: JoinReport) -> None:
        if self.bounds is None:
            self.unplaced_incomplete.append(stamps)
            return
        if self.unplaced_incomplete:
            stamps = np.concatenate([*self.unplaced_incomplete, stamps])
            self.unplaced_incomplete = []
        report.incomplete_steps += int(self._inside_count(stamps))

    def _inside_count(self, stamps: IntArray) -> int:
        assert self.bounds is not None
        start, end = self.bounds
        keep = np.ones(stamps.size, dtype=bool)
        if start is not None:
            keep &= stamps >= start
        if end is not None:
            keep &= stamps < end
        return int(np.count_nonzero(keep))


def _at(part: _Part, stamps: IntArray) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Values of ``part`` at ``stamps`` (NaN where it has none) and where it had them."""
    index = np.searchsorted(part.stamps, stamps)
    clipped = np.minimum(index, part.stamps.size - 1)
    found = (index < part.stamps.size) & (part.stamps[clipped] == stamps)
    values = np.full((stamps.size, part.values.shape[1]), np.nan)
    values[found] = part.values[clipped[found]]
    return values, found


def _columns(complete: IntArray, ready: Mapping[str, _Part], position: str) -> dict[str, np.ndarray]:
    measured, command = ready["measured"], ready["command"]
    columns: dict[str, np.ndarray] = {
        "t_ns": complete,
        "reference": _at(ready["reference"], complete)[0],
        "position": _at(ready[position], complete)[0],
        "measured": _at(measured, complete)[0],
        "command": _at(command, complete)[0],
        "latency": command.log_times[np.searchsorted(command.stamps, complete)]
        - measured.log_times[np.searchsorted(measured.stamps, complete)],
    }
    for optional in ("applied", "estimate"):
        part = ready.get(optional)
        columns[optional] = (
            np.full((complete.size, 2), np.nan) if part is None else _at(part, complete)[0][:, :2]
        )
    for series, part in ready.items():
        if series.startswith(_INTERNAL):
            columns[series] = _at(part, complete)[0][:, :2]
    return columns


class _Rebuffer:
    """Cuts a stream of column batches into blocks of exactly ``size`` steps (the last one fewer)."""

    def __init__(self, size: int) -> None:
        self.size = size
        self.parts: list[dict[str, np.ndarray]] = []
        self.count = 0

    def add(self, columns: dict[str, np.ndarray]) -> Iterator[dict[str, np.ndarray]]:
        self.parts.append(columns)
        self.count += int(columns["t_ns"].size)
        while self.count >= self.size:
            joined = _concatenate(self.parts)
            yield {key: values[: self.size] for key, values in joined.items()}
            rest = {key: values[self.size :] for key, values in joined.items()}
            self.count -= self.size
            self.parts = [rest] if self.count else []

    def flush(self) -> Iterator[dict[str, np.ndarray]]:
        if self.count:
            yield _concatenate(self.parts)
        self.parts, self.count = [], 0


def _concatenate(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    if len(parts) == 1:
        return parts[0]
    keys = list(dict.fromkeys(key for part in parts for key in part))
    joined = {}
    for key in keys:
        pieces = [part[key] if key in part else np.full((part["t_ns"].size, 2), np.nan) for part in parts]
        joined[key] = np.concatenate(pieces)
    return joined
