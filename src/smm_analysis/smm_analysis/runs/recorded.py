"""A recorded run as arrays: the stack's topics of a bag joined on the measurement stamps, held in memory."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from smm_bag.cdr import stamp_of
from smm_bag.errors import CorruptBagError
from smm_bag.manifest import RunManifest
from smm_bag.reader import BagReader

from smm_analysis.runs.stream import JOINTS, StepStream
from smm_analysis.runs.window import TimeWindow

__all__ = ["JOINTS", "RecordedRun", "load_run"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


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


def load_run(
    path: Path | str,
    *,
    progress: Callable[[int, int], None] | None = None,
    window: TimeWindow | None = None,
) -> RecordedRun:
    """Reads a bag of the stack into a :class:`RecordedRun` (every step in memory; see :class:`StepStream`).

    Optional quantities (effort, estimate, internals) are kept when present at every step, else None.

    Args:
        path: Bag folder.
        progress: Called with (messages read, messages to read).
        window: Steps to keep (default: all).

    Raises:
        BagError: Not a bag, truncated or corrupt (see :class:`BagReader`).
        MissingTopicsError: No reference, torque command or measurement in the bag.
        CorruptBagError: A message does not follow docs/INTERFACES.md.
    """
    stream = StepStream(path, window=window, progress=progress)
    blocks = list(stream.blocks())

    def joined(values: list[FloatArray]) -> FloatArray | None:
        array = np.concatenate(values)
        return array if bool(np.all(np.isfinite(array))) else None

    keys = list(dict.fromkeys(key for block in blocks for key in block.internals))
    internals = {}
    for key in keys:
        if all(key in block.internals for block in blocks):
            values = joined([block.internals[key] for block in blocks])
            if values is not None:
                internals[key] = values
    return RecordedRun(
        bag=stream.bag,
        manifest=stream.manifest,
        t_ns=np.concatenate([block.t_ns for block in blocks]),
        reference=np.concatenate([block.reference for block in blocks]),
        position=np.concatenate([block.position for block in blocks]),
        position_source=stream.position_source,
        measured_position=np.concatenate([block.measured_position for block in blocks]),
        command_torque=np.concatenate([block.command_torque for block in blocks]),
        applied_torque=joined([block.applied_torque for block in blocks]),
        disturbance_estimate=joined([block.disturbance_estimate for block in blocks]),
        internals=internals,
        latency_ns=np.concatenate([block.latency_ns for block in blocks]),
        incomplete_steps=stream.report.incomplete_steps,
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
