"""A recorded run as arrays: the stack's topics of a bag decoded and aligned on the measurement stamps."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from smm_bag.bulk import decode_arrays, decode_joint_states
from smm_bag.cdr import stamp_of
from smm_bag.errors import CorruptBagError, MissingTopicsError
from smm_bag.manifest import RunManifest
from smm_bag.reader import BagReader

__all__ = ["JOINTS", "RecordedRun", "load_run"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
JOINTS = ("alpha", "beta")
_REFERENCE_ROWS = ("position", "velocity", "acceleration")


@dataclass(frozen=True, eq=False)
class RecordedRun:
    """The control-relevant signals of one bag at the N control steps present on every required topic.

    Attributes:
        bag: Bag folder.
        manifest: The run manifest (defaults where the bag has none).
        t_ns: Measurement stamps (ns), strictly increasing, shape (N,).
        reference: q_d, q_d', q_d'' (rad, rad/s, rad/s^2), shape (N, 3, 2).
        position: Position the errors are measured on (rad), shape (N, 2).
        position_source: ``"ground truth"`` (``ground_truth`` topic) or ``"measured"`` (``joint_states``).
        measured_position: Encoder position given to the controller (rad), shape (N, 2).
        command_torque: ``torque_command`` (N m), shape (N, 2).
        applied_torque: Torque applied over the previous interval (``joint_states`` effort; N m), shape
            (N, 2), or None when the plant sent no effort.
        disturbance_estimate: xi~ (N m), shape (N, 2), or None when not recorded.
        internals: Rows of ``controller_internals`` and ``observer_state`` by quantity name, each (N, 2).
        latency_ns: Receive time of the command minus receive time of its measurement (ns), shape (N,).
        incomplete_steps: Stamps seen on some required topics but not all (left out).
    """

    bag: Path
    manifest: RunManifest
    t_ns: IntArray
    reference: FloatArray
    position: FloatArray
    position_source: str
    measured_position: FloatArray
    command_torque: FloatArray
    applied_torque: FloatArray | None
    disturbance_estimate: FloatArray | None
    internals: Mapping[str, FloatArray] = field(default_factory=dict)
    latency_ns: IntArray | None = None
    incomplete_steps: int = 0

    @property
    def desired_position(self) -> FloatArray:
        """q_d (rad), shape (N, 2)."""
        return self.reference[:, 0, :]

    @property
    def time_s(self) -> FloatArray:
        """Seconds since the first step, shape (N,)."""
        seconds: FloatArray = (self.t_ns - self.t_ns[0]).astype(np.float64) / 1e9
        return seconds

    @property
    def label(self) -> str:
        """Controller name from the manifest, else the bag folder's name."""
        return self.manifest.controller or self.bag.name


@dataclass
class _Series:
    """One topic's values by stamp: sorted unique stamps, values (n, k), receive times; last copy wins."""

    stamps: IntArray
    values: FloatArray
    log_times: IntArray

    @classmethod
    def build(cls, stamps: IntArray, values: FloatArray, log_times: IntArray) -> _Series:
        order = np.argsort(stamps, kind="stable")
        stamps, values, log_times = stamps[order], values[order], log_times[order]
        last = np.ones(stamps.size, dtype=bool)
        last[:-1] = stamps[1:] != stamps[:-1]  # of equal stamps keep the last received
        return cls(stamps[last], values[last], log_times[last])

    def at(self, stamps: IntArray) -> FloatArray:
        return self.values[np.searchsorted(self.stamps, stamps)]

    def covers(self, stamps: IntArray) -> bool:
        index = np.searchsorted(self.stamps, stamps)
        return bool(np.all(index < self.stamps.size)) and bool(
            np.all(self.stamps[np.minimum(index, self.stamps.size - 1)] == stamps)
        )


def _joint_series(topic: str, buffers: list[bytes], log_times: IntArray, field: str) -> _Series | None:
    count = len(buffers)
    stamps = np.empty(count, dtype=np.int64)
    values = np.full((count, 2), np.nan)
    present = np.zeros(count, dtype=bool)
    for indices, columns in decode_joint_states(buffers):
        order = _joint_order(columns.names, topic)
        source = getattr(columns, field)
        stamps[indices] = columns.stamps
        if source is None or source.shape[1] == 0:
            continue
        if source.shape[1] <= max(order):
            raise CorruptBagError(f"{topic}: JointState {field} has {source.shape[1]} values for 2 joints")
        values[indices] = source[:, list(order)]
        present[indices] = True
    if not np.any(present):
        return None
    return _Series.build(stamps[present], values[present], log_times[present])


def _array_series(
    topic: str, buffers: list[bytes], log_times: IntArray, check: Callable[[tuple[str, ...], int], None]
) -> _Series:
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
    return _Series.build(stamps, values, log_times)


def _labelled_series(topic: str, buffers: list[bytes], log_times: IntArray) -> dict[str, _Series]:
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
        quantity: _Series.build(np.concatenate(s), np.concatenate(v), np.concatenate(t))
        for quantity, (s, v, t) in rows.items()
    }


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


def load_run(path: Path | str, *, progress: Callable[[int, int], None] | None = None) -> RecordedRun:
    """Reads a bag of the stack into a :class:`RecordedRun`.

    Args:
        path: Bag folder.
        progress: Called with (messages read, messages to read).

    Raises:
        BagError: Not a bag, truncated or corrupt (see :class:`BagReader`).
        MissingTopicsError: No reference, torque command or measurement in the bag.
        CorruptBagError: A message does not follow docs/INTERFACES.md.
    """
    bag = Path(path)
    with BagReader(bag) as reader:
        manifest = RunManifest.from_custom_data(reader.metadata.custom_data)
        name = manifest.topic
        joint_states, ground_truth = name("joint_states"), name("ground_truth")
        reference_topic, command_topic = name("reference"), name("torque_command")
        estimate_topic = name("disturbance_estimate")
        labelled_topics = (name("controller_internals"), name("observer_state"))
        reader.require((joint_states, reference_topic, command_topic))
        counts = {topic.name: topic.message_count for topic in reader.metadata.topics}
        wanted = [
            joint_states,
            ground_truth,
            reference_topic,
            command_topic,
            estimate_topic,
            *labelled_topics,
        ]
        wanted = [topic for topic in wanted if counts.get(topic, 0) > 0]
        total = sum(counts[topic] for topic in wanted)
        buffers: dict[str, list[bytes]] = {topic: [] for topic in wanted}
        times: dict[str, list[int]] = {topic: [] for topic in wanted}
        read = 0
        for topic, log_time, data in reader.raw_messages(wanted):
            buffers[topic].append(data)
            times[topic].append(log_time)
            read += 1
            if progress is not None and read % 100_000 == 0:
                progress(read, total)
        if progress is not None:
            progress(read, total)

    def log_times(topic: str) -> IntArray:
        return np.array(times[topic], dtype=np.int64)

    def reference_layout(labels: tuple[str, ...], width: int) -> None:
        if _items(labels, "order") != _REFERENCE_ROWS or _items(labels, "joint") != JOINTS or width != 6:
            raise CorruptBagError(f"{reference_topic}: not a 3x2 reference (labels {labels})")

    def torque_layout(labels: tuple[str, ...], width: int) -> None:
        if _items(labels, "joint") != JOINTS or width != 2:
            raise CorruptBagError(f"{command_topic}: {width} values, expected 2 (labels {labels})")

    def estimate_layout(labels: tuple[str, ...], width: int) -> None:
        if _items(labels, "joint") != JOINTS or width < 2:
            raise CorruptBagError(f"{estimate_topic}: not a per-joint estimate (labels {labels})")

    measured = _joint_series(joint_states, buffers[joint_states], log_times(joint_states), "position")
    if measured is None:
        raise MissingTopicsError(f"{bag}: {joint_states} has no positions")
    applied = _joint_series(joint_states, buffers[joint_states], log_times(joint_states), "effort")
    truth = (
        _joint_series(ground_truth, buffers[ground_truth], log_times(ground_truth), "position")
        if ground_truth in buffers
        else None
    )
    reference = _array_series(
        reference_topic, buffers[reference_topic], log_times(reference_topic), reference_layout
    )
    command = _array_series(command_topic, buffers[command_topic], log_times(command_topic), torque_layout)
    estimate = (
        _array_series(estimate_topic, buffers[estimate_topic], log_times(estimate_topic), estimate_layout)
        if estimate_topic in buffers
        else None
    )
    labelled: dict[str, _Series] = {}
    for topic in labelled_topics:
        if topic in buffers:
            labelled.update(_labelled_series(topic, buffers[topic], log_times(topic)))
    del buffers

    source, position = ("ground truth", truth) if truth is not None else ("measured", measured)
    required = (measured, reference, command, position)
    complete = required[0].stamps
    for series in required[1:]:
        complete = np.intersect1d(complete, series.stamps, assume_unique=True)
    every = np.unique(np.concatenate([series.stamps for series in required]))
    if complete.size < 2:
        raise MissingTopicsError(
            f"{bag}: fewer than 2 control steps have a measurement, a reference and a torque command "
            f"with the same stamp ({complete.size} found)"
        )

    def optional(series: _Series | None) -> FloatArray | None:
        if series is None or not series.covers(complete):
            return None
        return series.at(complete)[:, :2]

    internals = {key: values for key, series in labelled.items() if (values := optional(series)) is not None}
    estimate_array = optional(estimate)
    if estimate_array is None and "disturbance_estimate" in internals:
        estimate_array = internals["disturbance_estimate"]
    latency = (
        command.log_times[np.searchsorted(command.stamps, complete)]
        - measured.log_times[np.searchsorted(measured.stamps, complete)]
    )
    return RecordedRun(
        bag=bag,
        manifest=manifest,
        t_ns=complete.astype(np.int64),
        reference=reference.at(complete).reshape(complete.size, 3, 2),
        position=position.at(complete),
        position_source=source,
        measured_position=measured.at(complete),
        command_torque=command.at(complete),
        applied_torque=optional(applied),
        disturbance_estimate=estimate_array,
        internals=internals,
        latency_ns=latency,
        incomplete_steps=int(every.size - complete.size),
    )


STEPPED_TOPICS = (
    "joint_states",
    "ground_truth",
    "reference",
    "torque_command",
    "joint_states_filtered",
    "disturbance_estimate",
)
"""The stack topics with one sample per control step (relative names), besides ``/clock``."""


def stamps_per_topic(path: Path | str) -> dict[str, frozenset[int]]:
    """The distinct stamps (ns) on each stepped topic the bag holds (``STEPPED_TOPICS`` and ``/clock``).

    A lockstep simulator re-publishes a measurement until it is answered, so a topic may hold a stamp more
    than once: distinct stamps, not messages, are what to compare with the simulator's step count.

    Raises:
        BagError: Not a bag, truncated or corrupt (see :class:`BagReader`).
    """
    with BagReader(Path(path)) as reader:
        manifest = RunManifest.from_custom_data(reader.metadata.custom_data)
        types = reader.topics
        wanted = [topic for topic in (*map(manifest.topic, STEPPED_TOPICS), "/clock") if topic in types]
        stamps: dict[str, set[int]] = {topic: set() for topic in wanted}
        for topic, _, data in reader.raw_messages(wanted):
            stamp = stamp_of(types[topic], data)
            if stamp is None:
                raise CorruptBagError(f"{path}: a message on {topic} has no stamp")
            stamps[topic].add(stamp)
    return {topic: frozenset(values) for topic, values in stamps.items()}
