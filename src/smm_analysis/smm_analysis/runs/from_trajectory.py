"""Writes an offline closed-loop run (``smm_analysis.closed_loop.Trajectory``) as the graph's topics in a bag.

The messages are those the lockstep graph publishes for the same run (docs/INTERFACES.md): per step k the
measurement ``joint_states`` (encoder position, effort = torque applied over the previous interval),
``ground_truth``, ``reference``, ``torque_command`` and ``controller_internals``, all stamped t_k; log times
are t_k plus ``epoch_ns`` plus a small per-topic offset in the graph's order. Used for the committed sample
bag, the benchmark's long bags, and tests that need a run whose metrics are known.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
from smm_bag.cdr import encode_float64_multi_array, encode_joint_state
from smm_bag.manifest import RunManifest
from smm_bag.metadata import BagMetadata
from smm_bag.qos import QosProfile
from smm_bag.writer import BagWriter, WriterOptions

from smm_analysis.closed_loop import Trajectory

__all__ = ["write_trajectory_bag"]

_NAMES = ("alpha", "beta")
_JOINT_DIM = "joint:alpha,beta"
_REFERENCE_DIMS = (("order:position,velocity,acceleration", 3, 6), (_JOINT_DIM, 2, 2))
_CONTROL = QosProfile(depth=10)
_DIAGNOSTIC = QosProfile(depth=100)


def _stamp_dim(stamp_ns: int) -> tuple[str, int, int]:
    return (f"stamp_ns:{stamp_ns}", 1, 1)


def write_trajectory_bag(
    trajectory: Trajectory,
    path: Path | str,
    *,
    options: WriterOptions | None = None,
    epoch_ns: int = 1_700_000_000_000_000_000,
    version: str = "",
    internals: bool = True,
    progress: Callable[[int, int], None] | None = None,
    repeat: int = 1,
    then: Sequence[Trajectory] = (),
    parameter_events: Sequence[tuple[int, bytes]] = (),
    measured_torque: np.ndarray | None = None,
    plant: str = "sim",
) -> BagMetadata:
    """Writes the run as a bag; returns its metadata.

    Args:
        trajectory: The run.
        path: New bag folder.
        options: Writer options (the manifest is added to their custom data).
        epoch_ns: Wall-clock time of step 0 (ns) used for the log times.
        version: ``git describe`` for the manifest.
        internals: Also write ``controller_internals`` (every chain internal).
        progress: Called with (steps written, steps).
        repeat: Write the run this many times back to back, each copy's stamps after the previous
            copy's by one control period (long bags for benchmarks without holding a long run).
        then: Runs written after it (after the repeats), each likewise one period after the previous one
            (several experiments in one recording; the manifest is the first run's).
        parameter_events: ``(stamp ns, rcl_interfaces/msg/ParameterEvent CDR)`` written on
            ``/parameter_events`` just before the first step stamped at or after it.
        measured_torque: The bridge's load-pressure torque at each step (N m), shape (N + 1, 2): written as
            ``hw_bridge_internals`` row ``measured_torque``, and no ``ground_truth`` (a bench's run).
        plant: The manifest's plant (``sim`` or ``hardware``).
    """
    if repeat < 1:
        raise ValueError(f"repeat must be >= 1, got {repeat}")
    if measured_torque is not None and (repeat != 1 or then):
        raise ValueError("measured_torque is written for one run, without repeat or then")
    parts = [trajectory] * repeat + list(then)
    manifest = RunManifest(
        version=version,
        scenario=trajectory.scenario,
        seed=trajectory.seed,
        plant=plant,
        controller=trajectory.controller,
        control_period_ns=round(trajectory.control_period * 1e9),
        clock_mode="lockstep",
    )
    base = options if options is not None else WriterOptions()
    chosen = WriterOptions(
        max_duration_ns=base.max_duration_ns,
        max_size_bytes=base.max_size_bytes,
        compression=base.compression,
        flush_interval_ns=base.flush_interval_ns,
        chunk_size=base.chunk_size,
        fsync=base.fsync,
        custom_data={**base.custom_data, **manifest.to_custom_data()},
        ros_distro=base.ros_distro,
        period_ns=manifest.control_period_ns,
        stamped_topics=base.stamped_topics,
    )
    topic = manifest.topic
    keys: tuple[str, ...] = tuple(trajectory.internals) if internals else ()
    with BagWriter(path, chosen) as writer:
        writer.create_topic(topic("joint_states"), "sensor_msgs/msg/JointState", [_CONTROL])
        if measured_torque is None:
            writer.create_topic(topic("ground_truth"), "sensor_msgs/msg/JointState", [_DIAGNOSTIC])
        else:
            writer.create_topic(topic("hw_bridge_internals"), "std_msgs/msg/Float64MultiArray", [_DIAGNOSTIC])
        writer.create_topic(topic("reference"), "std_msgs/msg/Float64MultiArray", [_CONTROL])
        writer.create_topic(topic("torque_command"), "std_msgs/msg/Float64MultiArray", [_CONTROL])
        if keys:
            writer.create_topic(
                topic("controller_internals"), "std_msgs/msg/Float64MultiArray", [_DIAGNOSTIC]
            )
        if parameter_events:
            writer.create_topic("/parameter_events", "rcl_interfaces/msg/ParameterEvent", [_DIAGNOSTIC])
        events = sorted(parameter_events, key=lambda event: event[0])
        total = sum(part.t_ns.size for part in parts)
        done = 0
        offset = 0
        for part in parts:
            shift = offset - int(part.t_ns[0])
            offset += int(part.t_ns[-1] - part.t_ns[0]) + manifest.control_period_ns
            done = _write_steps(
                writer,
                part,
                topic=topic,
                shift=shift,
                keys=keys,
                events=events,
                epoch_ns=epoch_ns,
                done=done,
                measured=measured_torque,
                total=total,
                progress=progress,
            )
        return writer.close()


def _write_steps(
    writer: BagWriter,
    trajectory: Trajectory,
    *,
    topic: Callable[[str], str],
    shift: int,
    keys: tuple[str, ...],
    events: list[tuple[int, bytes]],
    epoch_ns: int,
    done: int,
    total: int,
    progress: Callable[[int, int], None] | None,
    measured: np.ndarray | None = None,
) -> int:
    """Writes one run's steps, stamps moved by ``shift`` (ns), and the events due; returns the steps done.

    ``measured``: the bridge's measured torque per step, written in place of the ground truth.
    """
    names = list(_NAMES)
    internal_rows: Mapping[str, np.ndarray] = trajectory.internals
    internal_dims = (
        (("quantity:" + ",".join(keys), len(keys), 2 * len(keys)), (_JOINT_DIM, 2, 2)) if keys else ()
    )
    for k in range(trajectory.t_ns.size):
        stamp = int(trajectory.t_ns[k]) + shift
        while events and events[0][0] <= stamp:
            writer.write("/parameter_events", events.pop(0)[1], epoch_ns + stamp)
        at = epoch_ns + stamp
        applied = trajectory.applied_torque[k - 1].tolist() if k > 0 else [0.0, 0.0]
        writer.write(
            topic("reference"),
            encode_float64_multi_array(
                (*_REFERENCE_DIMS, _stamp_dim(stamp)), trajectory.reference[k].ravel().tolist()
            ),
            at,
        )
        writer.write(
            topic("joint_states"),
            encode_joint_state(stamp, names, trajectory.measured_position[k].tolist(), [], applied),
            at + 10_000,
        )
        if measured is None:
            writer.write(
                topic("ground_truth"),
                encode_joint_state(
                    stamp,
                    names,
                    trajectory.position[k].tolist(),
                    trajectory.velocity[k].tolist(),
                    applied,
                ),
                at + 20_000,
            )
        else:
            writer.write(
                topic("hw_bridge_internals"),
                encode_float64_multi_array(
                    (("quantity:measured_torque", 1, 2), (_JOINT_DIM, 2, 2), _stamp_dim(stamp)),
                    measured[k].tolist(),
                ),
                at + 300_000,
            )
        writer.write(
            topic("torque_command"),
            encode_float64_multi_array(
                ((_JOINT_DIM, 2, 2), _stamp_dim(stamp)), trajectory.command_torque[k].tolist()
            ),
            at + 200_000,
        )
        if keys:
            rows = [value for key in keys for value in internal_rows[key][k].tolist()]
            writer.write(
                topic("controller_internals"),
                encode_float64_multi_array((*internal_dims, _stamp_dim(stamp)), rows),
                at + 210_000,
            )
        done += 1
        if progress is not None and (done % 10_000 == 1 or done == total):
            progress(done, total)
    return done
