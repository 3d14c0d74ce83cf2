"""The streamed analysis (runs.stream, runs.accumulate): the in-memory indices within the stated tolerance,
whatever the writer's chunking; joins within the reorder window, counts what comes later."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag.bag_helpers import MAKERS, T0
from smm_analysis.closed_loop import Trajectory, run_closed_loop
from smm_analysis.metrics import end_effector_errors, joint_indices, step_metrics
from smm_analysis.reproduction.reproduce import evaluate_run
from smm_analysis.runs.accumulate import SUM_RELATIVE_TOLERANCE
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_analysis.runs.indices import RunMetrics, evaluate_stream
from smm_analysis.runs.stream import StepStream
from smm_analysis.runs.window import TimeWindow, parse_bound
from smm_analysis.scenarios import get_scenario
from smm_bag.writer import BagWriter, WriterOptions

from smm_dynamics import SMMParameters

JOINTS = ("alpha", "beta")
SUMMED = ("Ave", "RMS", "eps_u", "du_rms")


@pytest.fixture(scope="module")
def case2(tmp_path_factory: pytest.TempPathFactory) -> tuple[Trajectory, Path, Path]:
    """A 2 s case-2 run written twice: in 4 KiB chunks and in the writer's default (768 KiB) chunks."""
    trajectory = run_closed_loop(get_scenario("case2").with_duration(2.0), "fpdeso", seed=5)
    folder = tmp_path_factory.mktemp("stream")
    small, large = folder / "small_chunks", folder / "default_chunks"
    write_trajectory_bag(trajectory, small, options=WriterOptions(chunk_size=4096))
    write_trajectory_bag(trajectory, large)
    return trajectory, small, large


def _streamed(bag: Path, **options: int) -> RunMetrics:
    return evaluate_stream(StepStream(bag, **options))  # type: ignore[arg-type]


def _assert_within_tolerance(streamed: RunMetrics, joints: dict, cartesian: dict) -> None:  # type: ignore[type-arg]
    for joint in JOINTS:
        assert streamed.joints[joint].Ma == joints[joint].Ma  # a maximum is exact
        for name in SUMMED:
            expected = getattr(joints[joint], name)
            assert getattr(streamed.joints[joint], name) == pytest.approx(
                expected, rel=SUM_RELATIVE_TOLERANCE
            )
    for axis in ("x", "y", "z"):
        assert streamed.end_effector[axis].max_mm == cartesian[axis].max_mm
        assert streamed.end_effector[axis].rms_mm == pytest.approx(
            cartesian[axis].rms_mm, rel=SUM_RELATIVE_TOLERANCE
        )


def test_streamed_indices_equal_the_in_memory_computation_within_the_stated_tolerance(
    case2: tuple[Trajectory, Path, Path],
) -> None:
    trajectory, small, _ = case2
    offline = evaluate_run(trajectory, get_scenario("case2").with_duration(2.0))
    # Small blocks and read batches: many block sums, a join across many batches.
    streamed = _streamed(small, block_steps=97, read_batch=1000)
    assert streamed.run.steps == trajectory.t_ns.size  # counts exact
    assert streamed.run.incomplete_steps == 0 and streamed.run.late_messages == {}
    _assert_within_tolerance(streamed, dict(offline.joints), dict(offline.end_effector))


def test_the_same_run_chunked_two_ways_gives_identical_results(case2: tuple[Trajectory, Path, Path]) -> None:
    _, small, large = case2
    first, second = _streamed(small), _streamed(large)
    assert first.joints == second.joints
    assert first.end_effector == second.end_effector
    assert first.run.latency == second.run.latency
    # How the reader batches the messages does not matter either: the sums are cut by step number.
    assert _streamed(small, read_batch=777).joints == first.joints


def test_a_step_bag_gives_the_step_metrics_of_the_in_memory_functions(tmp_path: Path) -> None:
    scenario = get_scenario("step").with_duration(0.6)
    trajectory = run_closed_loop(scenario, "fpdeso", seed=0)
    write_trajectory_bag(trajectory, tmp_path / "step")
    streamed = _streamed(tmp_path / "step", block_steps=50, read_batch=300)
    offline = evaluate_run(trajectory, scenario)
    assert streamed.step is not None and offline.step is not None
    for joint in JOINTS:
        assert streamed.step[joint] == offline.step[joint]


def test_a_window_gives_the_indices_of_the_same_steps_in_memory(case2: tuple[Trajectory, Path, Path]) -> None:
    trajectory, small, _ = case2
    window = TimeWindow(parse_bound("0.5"), parse_bound("1.25"))
    streamed = evaluate_stream(StepStream(small, window=window, block_steps=64, read_batch=500))
    keep = (trajectory.t_ns >= trajectory.t_ns[0] + 500_000_000) & (
        trajectory.t_ns < trajectory.t_ns[0] + 1_250_000_000
    )
    t_ns = trajectory.t_ns[keep]
    assert streamed.run.steps == t_ns.size == 750
    assert (streamed.run.first_ns, streamed.run.last_ns) == (int(t_ns[0]), int(t_ns[-1]))
    desired, position = trajectory.desired_position[keep], trajectory.position[keep]
    joints = joint_indices(t_ns, desired, position, trajectory.command_torque[keep])
    _assert_within_tolerance(
        streamed, joints, dict(end_effector_errors(t_ns, desired, position, SMMParameters()))
    )
    # The same window in bag time.
    absolute = TimeWindow(parse_bound(f"@{t_ns[0] / 1e9:.9f}"), parse_bound(f"@{(t_ns[-1] + 1) / 1e9:.9f}"))
    assert (
        evaluate_stream(StepStream(small, window=absolute)).joints
        == evaluate_stream(StepStream(small, window=window)).joints
    )


def _handmade_bag(path: Path, order: list[tuple[int, str]]) -> Path:
    """A bag of the three required topics whose messages are written in ``order`` of (step, topic)."""
    with BagWriter(path, WriterOptions(chunk_size=2048)) as writer:
        for topic in MAKERS:
            kind = "sensor_msgs/msg/JointState" if "joint" in topic else "std_msgs/msg/Float64MultiArray"
            writer.create_topic(topic, kind)
        for number, (k, topic) in enumerate(order):
            writer.write(topic, MAKERS[topic](k), T0 + number * 1000)
    return path


def test_messages_within_the_reorder_window_are_joined_and_later_ones_counted(tmp_path: Path) -> None:
    steps = 3000  # 1 ms apart: 3 s of stamps
    order = [
        (k, topic)
        for k in range(steps)
        for topic in MAKERS
        if not (topic.endswith("command") and k in (100, 200))
    ]
    # The command of step 100 comes 0.6 s of stamps late (inside the 1 s window), that of step 200 2.5 s late.
    order.insert(700 * 3, (100, "/smm/torque_command"))
    order.append((200, "/smm/torque_command"))
    bag = _handmade_bag(tmp_path / "reordered", order)
    stream = StepStream(bag, read_batch=256, block_steps=128)
    blocks = list(stream.blocks())
    stamps = np.concatenate([block.t_ns for block in blocks])
    assert 100 * 1_000_000 in stamps and 200 * 1_000_000 not in stamps
    assert stream.report.steps == steps - 1
    assert stream.report.incomplete_steps == 1
    assert stream.report.late_messages == {"/smm/torque_command": 1}
    # In memory everything is joined: the streamed join differs only by what came too late.
    assert np.all(np.diff(stamps) > 0)


def test_stamps_repeated_in_the_window_keep_the_last_received(tmp_path: Path) -> None:
    order = [(k, topic) for k in range(50) for topic in MAKERS]
    order.insert(30, (5, "/smm/joint_states"))  # a re-publication of step 5's measurement
    bag = _handmade_bag(tmp_path / "repeated", order)
    stream = StepStream(bag, read_batch=7)
    assert sum(block.t_ns.size for block in stream.blocks()) == 50
    assert stream.report.incomplete_steps == 0


def test_the_streamed_rms_is_the_trapezoid_of_eq_44_on_uneven_stamps(tmp_path: Path) -> None:
    # Uneven stamps across block boundaries: the trapezoid's carried term is the in-memory one.
    k = np.array([i + (i * i) // 300 for i in range(400)])
    bag = _handmade_bag(tmp_path / "uneven", [(int(step), topic) for step in k for topic in MAKERS])
    streamed = _streamed(bag, block_steps=3, read_batch=5)
    t_ns = k.astype(np.int64) * 1_000_000
    desired = np.column_stack([0.01 * k, np.zeros(k.size)])
    position = np.column_stack([0.001 * k, -0.002 * k])
    torque = np.column_stack([k.astype(np.float64), -k.astype(np.float64)])
    expected = joint_indices(t_ns, desired, position, torque)
    for joint in JOINTS:
        assert streamed.joints[joint].Ma == expected[joint].Ma
        for name in SUMMED:
            assert getattr(streamed.joints[joint], name) == pytest.approx(
                getattr(expected[joint], name), rel=SUM_RELATIVE_TOLERANCE
            )


def test_step_metrics_stream_across_blocks_as_in_memory() -> None:
    from smm_analysis.runs.accumulate import _StepResponse

    t_ns = np.arange(2000, dtype=np.int64) * 1_000_000
    t_s = t_ns.astype(np.float64) / 1e9
    response = 1.0 - np.exp(-t_s / 0.1) * np.cos(t_s * 30.0)
    expected = step_metrics(t_ns, response, 1.0, initial=0.0)
    for size in (1, 2, 7, 333, 2000):
        streamed = _StepResponse(1.0, 0.0)
        for start in range(0, 2000, size):
            streamed.add(t_s[start : start + size], response[start : start + size])
        assert streamed.result() == expected


@pytest.mark.parametrize("wall_ns", [0, 1_796_000_000_000_000_000], ids=["host clock", "board clock"])
def test_a_rehearsal_stamped_an_hour_ahead_is_left_out_and_the_run_after_it_is_joined(
    tmp_path: Path, wall_ns: int
) -> None:
    """The preflight publishes its rehearsal stamped an hour ahead, then the run's stamps.

    ``wall_ns``: the log clock's reading at stamp 0: a simulator stamps on the host's clock, the bridge with
    the board's time since its start (log times in the recorder's wall clock).
    """
    hour = 3_600_000  # steps of 1 ms
    steps = 2000
    path = tmp_path / "rehearsed"
    with BagWriter(path, WriterOptions(chunk_size=2048)) as writer:
        for topic in MAKERS:
            kind = "sensor_msgs/msg/JointState" if "joint" in topic else "std_msgs/msg/Float64MultiArray"
            writer.create_topic(topic, kind)
        # recorded as received: log time = the step's true time, slightly after its stamp
        for k in range(2 * steps):
            stamp_step = k + hour if k < steps else k
            for topic in MAKERS:
                writer.write(topic, MAKERS[topic](stamp_step), wall_ns + k * 1_000_000 + 200_000)
    stream = StepStream(path, read_batch=256, block_steps=128)
    stamps = np.concatenate([block.t_ns for block in stream.blocks()])
    assert stamps.tolist() == [k * 1_000_000 for k in range(steps, 2 * steps)]  # the run, whole
    assert stream.report.ahead_messages == {topic: steps for topic in MAKERS}  # per message, once
    assert stream.report.late_messages == {}
