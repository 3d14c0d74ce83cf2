"""A recorded run as arrays: the stack's topics of a bag decoded and aligned on the measurement stamps."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from smm_bag.cdr import DecodedArray, decode_float64_multi_array, decode_joint_state
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


def _joint_order(names: tuple[str, ...], topic: str) -> tuple[int, int]:
    try:
        return names.index("alpha"), names.index("beta")
    except ValueError:
        raise CorruptBagError(f"{topic}: JointState names {list(names)} lack alpha or beta") from None


def _pair(values: tuple[float, ...], order: tuple[int, int], topic: str, what: str) -> tuple[float, float]:
    if len(values) <= max(order):
        raise CorruptBagError(f"{topic}: JointState {what} has {len(values)} values for 2 joints")
    return values[order[0]], values[order[1]]


def _checked_array(decoded: DecodedArray, topic: str) -> tuple[int, tuple[str, ...] | None]:
    stamp = decoded.stamp_ns
    if stamp is None:
        raise CorruptBagError(f"{topic}: Float64MultiArray without a stamp_ns dimension")
    joints = decoded.items("joint")
    if joints != JOINTS:
        raise CorruptBagError(f"{topic}: joint dimension {joints} is not (alpha, beta)")
    return stamp, decoded.items("quantity")


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

        measured: dict[int, tuple[float, float]] = {}
        applied: dict[int, tuple[float, float]] = {}
        truth: dict[int, tuple[float, float]] = {}
        reference: dict[int, tuple[float, ...]] = {}
        command: dict[int, tuple[float, ...]] = {}
        estimate: dict[int, tuple[float, ...]] = {}
        labelled: dict[str, dict[int, tuple[float, float]]] = {}
        measured_at: dict[int, int] = {}
        commanded_at: dict[int, int] = {}

        report = None if progress is None else (lambda read: progress(read, total))
        for message in reader.messages(wanted, ordered=False, progress=report):
            topic = message.topic
            if topic in (joint_states, ground_truth):
                state = decode_joint_state(message.data)
                order = _joint_order(state.name, topic)
                position = _pair(state.position, order, topic, "position")
                if topic == joint_states:
                    measured[state.stamp_ns] = position
                    measured_at[state.stamp_ns] = message.log_time_ns
                    if state.effort:
                        applied[state.stamp_ns] = _pair(state.effort, order, topic, "effort")
                else:
                    truth[state.stamp_ns] = position
                continue
            decoded = decode_float64_multi_array(message.data)
            stamp, quantities = _checked_array(decoded, topic)
            if topic == reference_topic:
                if decoded.items("order") != _REFERENCE_ROWS or len(decoded.data) != 6:
                    raise CorruptBagError(f"{topic}: not a 3x2 reference (dims {decoded.dims})")
                reference[stamp] = decoded.data
            elif topic == command_topic:
                if len(decoded.data) != 2:
                    raise CorruptBagError(f"{topic}: {len(decoded.data)} values, expected 2")
                command[stamp] = decoded.data
                commanded_at[stamp] = message.log_time_ns
            elif topic == estimate_topic:
                estimate[stamp] = decoded.data[:2]
            else:
                if quantities is None or len(decoded.data) != 2 * len(quantities):
                    raise CorruptBagError(f"{topic}: labelled array without a matching quantity dimension")
                data = decoded.data
                for row, quantity in enumerate(quantities):
                    labelled.setdefault(quantity, {})[stamp] = (data[2 * row], data[2 * row + 1])

    source, position_by_stamp = ("ground truth", truth) if truth else ("measured", measured)
    every = set(measured) | set(reference) | set(command) | set(position_by_stamp)
    complete = sorted(set(measured) & set(reference) & set(command) & set(position_by_stamp))
    if len(complete) < 2:
        raise MissingTopicsError(
            f"{bag}: fewer than 2 control steps have a measurement, a reference and a torque command "
            f"with the same stamp ({len(complete)} found)"
        )
    t_ns = np.array(complete, dtype=np.int64)

    def stack(table: Mapping[int, tuple[float, ...]], width: int) -> FloatArray:
        return np.array([table[stamp] for stamp in complete], dtype=np.float64).reshape(len(complete), width)

    def optional(table: Mapping[int, tuple[float, ...]]) -> FloatArray | None:
        if not table or any(stamp not in table for stamp in complete):
            return None
        return stack(table, 2)

    internals = {key: values for key, table in labelled.items() if (values := optional(table)) is not None}
    estimate_array = optional(estimate)
    if estimate_array is None and "disturbance_estimate" in internals:
        estimate_array = internals["disturbance_estimate"]
    latency = np.array([commanded_at[stamp] - measured_at[stamp] for stamp in complete], dtype=np.int64)
    return RecordedRun(
        bag=bag,
        manifest=manifest,
        t_ns=t_ns,
        reference=stack(reference, 6).reshape(len(complete), 3, 2),
        position=stack(position_by_stamp, 2),
        position_source=source,
        measured_position=stack(measured, 2),
        command_torque=stack(command, 2),
        applied_torque=optional(applied),
        disturbance_estimate=estimate_array,
        internals=internals,
        latency_ns=latency,
        incomplete_steps=len(every) - len(complete),
    )
