"""smm_sim_node (the glue around smm_sim.core): timers, publishers, message parsing, parameters, run end."""

from __future__ import annotations

import array
import json
import math
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from smm_sim.core import statistics_summary

pytestmark = pytest.mark.ros

PERIOD_NS = 1_000_000


class Harness:
    """A SimNode and a test node ("controller") in one private context and one executor."""

    def __init__(self, context: Any, **parameters: Any) -> None:
        import rclpy
        from rclpy.parameter import Parameter
        from sensor_msgs.msg import JointState
        from smm_msgs_py.qos import qos_for_topic
        from smm_sim.sim_node import SimNode
        from std_msgs.msg import Float64MultiArray

        from smm_msgs_py import topics
        from smm_node_runtime import make_executor

        overrides = [Parameter(name, value=value) for name, value in parameters.items()]
        self.sim = SimNode(context=context, parameter_overrides=overrides)
        self.peer = rclpy.create_node("test_peer", context=context)
        self.measurements: list[Any] = []
        self.truths: list[Any] = []
        self.peer.create_subscription(
            JointState, topics.JOINT_STATES, self.measurements.append, qos_for_topic(topics.JOINT_STATES)
        )
        self.peer.create_subscription(
            JointState, topics.GROUND_TRUTH, self.truths.append, qos_for_topic(topics.GROUND_TRUTH)
        )
        self.commands = self.peer.create_publisher(
            Float64MultiArray, topics.TORQUE_COMMAND, qos_for_topic(topics.TORQUE_COMMAND)
        )
        self.executor = make_executor(context)
        self.executor.add_node(self.sim)
        self.executor.add_node(self.peer)

    def spin_until(self, predicate: Any, timeout_s: float = 10.0) -> bool:
        from ros_harness import spin_until

        return spin_until(self.executor, predicate, timeout_s)

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def wait_matched(self) -> None:
        assert self.spin_until(
            lambda: self.commands.get_subscription_count() >= 1 and len(self.measurements) >= 1
        )

    def send(self, tau: Any, stamp_ns: int) -> None:
        from smm_msgs_py.conversions import torque_to_msg

        self.commands.publish(torque_to_msg(np.asarray(tau, dtype=float), stamp_ns))

    def send_raw(self, msg: Any) -> None:
        self.commands.publish(msg)

    def stamps(self) -> list[int]:
        from smm_msgs_py.conversions import stamp_to_ns

        return [stamp_to_ns(m.header.stamp) for m in self.measurements]

    def close(self) -> None:
        self.executor.shutdown()
        self.sim.destroy_node()
        self.peer.destroy_node()


@pytest.fixture
def make_harness(ros_context: Any) -> Iterator[Any]:
    created: list[Harness] = []

    def make(**parameters: Any) -> Harness:
        harness = Harness(ros_context, **parameters)
        created.append(harness)
        return harness

    yield make
    for harness in created:
        harness.close()


LOCKSTEP = {"clock_mode": "lockstep", "republish_period": 0.02}


def test_lockstep_does_not_advance_without_the_answering_command(make_harness: Any) -> None:
    h = make_harness(**LOCKSTEP)
    h.wait_matched()
    h.spin_until(lambda: len(h.measurements) >= 4)
    assert h.sim.core.steps == 0
    assert set(h.stamps()) == {0}, "an unanswered measurement must be re-published with the same stamp"
    assert h.sim.core.republished >= 3

    h.send([0.5, -0.5], 0)
    assert h.spin_until(lambda: h.sim.core.steps == 1)
    assert h.spin_until(lambda: PERIOD_NS in h.stamps())
    h.spin_for(0.1)
    assert h.sim.core.steps == 1, "one answer must give exactly one step"
    assert max(h.stamps()) == PERIOD_NS


def _bad_commands() -> list[tuple[str, Any]]:
    from smm_msgs_py.conversions import torque_to_msg

    nan = torque_to_msg(np.array([1.0, 2.0]), 0)
    nan.data = array.array("d", [math.nan, 2.0])
    inf = torque_to_msg(np.array([1.0, 2.0]), 0)
    inf.data = array.array("d", [1.0, math.inf])
    too_long = torque_to_msg(np.array([1.0, 2.0]), 0)
    too_long.data = array.array("d", [1.0, 2.0, 3.0])
    swapped_labels = torque_to_msg(np.array([1.0, 2.0]), 0)
    swapped_labels.layout.dim[0].label = "joint:beta,alpha"
    no_stamp = torque_to_msg(np.array([1.0, 2.0]), 0)
    no_stamp.layout.dim = no_stamp.layout.dim[:1]
    offset = torque_to_msg(np.array([1.0, 2.0]), 0)
    offset.layout.data_offset = 1
    return [
        ("nan", nan),
        ("inf", inf),
        ("too_long", too_long),
        ("swapped_labels", swapped_labels),
        ("no_stamp", no_stamp),
        ("data_offset", offset),
    ]


@pytest.mark.parametrize("clock_mode", ["lockstep", "realtime"])
def test_bad_commands_are_dropped_and_never_applied(make_harness: Any, clock_mode: str) -> None:
    h = make_harness(clock_mode=clock_mode, republish_period=0.02, command_timeout=0.5)
    h.wait_matched()
    bad = _bad_commands()
    for _, msg in bad:
        h.send_raw(msg)
    assert h.spin_until(lambda: h.sim.core.dropped_invalid == len(bad)), h.sim.core.statistics()
    h.spin_for(0.05)
    internals = h.sim.core.plant.internals
    np.testing.assert_array_equal(internals["commanded_torque"], [0.0, 0.0])
    truth = h.sim.core.plant.ground_truth
    # At rest at q = 0 with zero torque the plant stays exactly at the unstable equilibrium.
    np.testing.assert_array_equal(truth.position, [0.0, 0.0])
    np.testing.assert_array_equal(truth.velocity, [0.0, 0.0])
    if clock_mode == "lockstep":
        assert h.sim.core.steps == 0


def test_lockstep_run_ends_after_max_steps_with_a_complete_record(make_harness: Any, tmp_path: Path) -> None:
    from smm_msgs_py.conversions import joint_state_to_sample

    record = tmp_path / "run.npz"
    stats = tmp_path / "stats.json"
    h = make_harness(**LOCKSTEP, max_steps=20, record_file=str(record), stats_file=str(stats))
    h.wait_matched()
    answered: set[int] = set()

    def answer_pending() -> bool:
        for msg in h.measurements:
            sample = joint_state_to_sample(msg, require_effort=True)
            if sample.stamp_ns not in answered:
                answered.add(sample.stamp_ns)
                h.send(-2.0 * sample.position + 0.1, sample.stamp_ns)
        return h.sim.core.finished

    assert h.spin_until(answer_pending, timeout_s=20.0)
    assert h.sim.done.done() and h.sim.done.result() == 20
    data = np.load(record)
    np.testing.assert_array_equal(data["stamp_ns"], np.arange(21) * PERIOD_NS)
    np.testing.assert_array_equal(data["command_stamp_ns"], np.arange(20) * PERIOD_NS)
    assert data["position"].shape == (21, 2) and data["command"].shape == (20, 2)
    written = json.loads(stats.read_text())
    assert written["steps"] == 20
    # Every publication is counted, re-publications included: the measurements of steps 0..19 (the last
    # one ends the run unpublished). Ground truth goes out only while a reader is matched.
    published = {topic.rsplit("/", 1)[-1]: n for topic, n in written["published"].items()}
    assert published["joint_states"] == 20 + written["republished"]
    assert set(published) <= {"joint_states", "ground_truth", "clock"}
    assert all(n <= published["joint_states"] for n in published.values())
    summary = statistics_summary(h.sim.core.statistics())
    assert summary.startswith("20 steps at ") and "steps/s (lockstep)" in summary
    assert "latency" not in summary and "nan" not in summary  # no deadlines in lockstep


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("clock_mode", "fast", "clock_mode"),
        ("command_timeout", -1.0, "command_timeout"),
        ("command_timeout", 1e9, "command_timeout out of range"),  # in effect no timeout: refused
        ("command_timeout", 0.6, "command_timeout out of range"),
        ("republish_period", 0.0, "republish_period"),
        ("max_steps", -3, "max_steps"),
        ("noise_std", [-0.1, 0.0], "noise_std"),
        ("noise_std", [0.1], "noise_std"),
        ("disturbance", "wind", "disturbance"),
        ("joint_limits", [1.6, 1.0], "joint_limits"),
        ("initial_position", [1.4, 0.0], "initial_position"),
        ("torque_limit", [-1.0, 1.0], "torque_limit"),
        ("substeps", 0, "substeps"),
        ("params.I55", -0.1, "I55"),
    ],
)
def test_invalid_start_up_parameters_are_rejected_with_reason(
    ros_context: Any, name: str, value: Any, reason: str
) -> None:
    from rclpy.parameter import Parameter
    from smm_sim.sim_node import SimNode

    with pytest.raises(ValueError, match=reason):
        SimNode(context=ros_context, parameter_overrides=[Parameter(name, value=value)])


def test_live_parameter_changes_are_validated(make_harness: Any) -> None:
    from rclpy.parameter import Parameter

    h = make_harness(**LOCKSTEP)
    bad = h.sim.set_parameters([Parameter("command_timeout", value=-0.5)])[0]
    assert not bad.successful and "command_timeout" in bad.reason
    assert h.sim.config.command_timeout == 0.05
    huge = h.sim.set_parameters([Parameter("command_timeout", value=1e9)])[0]
    assert not huge.successful and "command_timeout out of range" in huge.reason and "Max: 0.5" in huge.reason
    assert h.sim.config.command_timeout == 0.05
    mode = h.sim.set_parameters([Parameter("clock_mode", value="realtime")])[0]
    assert not mode.successful and "clock_mode" in mode.reason
    plant = h.sim.set_parameters([Parameter("noise_std", value=[0.5, 0.5])])[0]
    assert not plant.successful
    assert h.sim.plant_parameters.noise_std == (0.0, 0.0)
    good = h.sim.set_parameters([Parameter("republish_period", value=0.5)])[0]
    assert good.successful, good.reason
    assert h.sim.config.republish_period == 0.5


def test_console_script_exits_2_on_an_invalid_parameter(ros_domain_id: int) -> None:
    from smm_bringup.graph_nodes import NodeSpec
    from smm_bringup.supervisor import resolve_executable

    spec = NodeSpec(
        "smm_sim", "smm_sim_node", "smm_sim_node", "smm_sim.sim_node:SimNode", parameters=(("substeps", 0),)
    )
    result = subprocess.run(
        spec.command_line(resolve_executable(spec)), capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert "substeps" in result.stderr


def test_a_diverging_plant_ends_the_run_as_failed(make_harness: Any, tmp_path: Path) -> None:
    from smm_sim.core import PlantDivergedError

    record = tmp_path / "diverged.npz"
    h = make_harness(**LOCKSTEP, record_file=str(record))
    h.wait_matched()
    h.send([1e300, -1e300], 0)  # finite, so accepted, but no integrator survives it
    assert h.spin_until(lambda: h.sim.core.finished)
    failure = h.sim.done.exception()
    assert isinstance(failure, PlantDivergedError)
    assert "non-finite" in str(failure)
    h.spin_for(0.1)
    assert h.sim.core.steps == 1, "a diverged plant must not step again"
    assert np.load(record)["command"].shape == (1, 2)


def test_lockstep_publishes_sim_time_on_clock_for_its_subscribers(make_harness: Any) -> None:
    from rosgraph_msgs.msg import Clock
    from smm_msgs_py.conversions import stamp_to_ns
    from smm_msgs_py.qos import clock_qos

    h = make_harness(**LOCKSTEP)
    clocks: list[Any] = []
    h.peer.create_subscription(Clock, "/clock", clocks.append, clock_qos())
    h.wait_matched()
    assert h.spin_until(lambda: h.sim.count_subscribers("/clock") >= 1)
    for step in range(3):
        h.send([0.0, 0.0], step * PERIOD_NS)
        assert h.spin_until(lambda step=step: h.sim.core.steps == step + 1)
    assert h.spin_until(lambda: any(stamp_to_ns(c.clock) == 3 * PERIOD_NS for c in clocks))
    times = {stamp_to_ns(c.clock) for c in clocks}
    assert {PERIOD_NS, 2 * PERIOD_NS, 3 * PERIOD_NS} <= times <= {k * PERIOD_NS for k in range(4)}


def test_realtime_status_goes_to_error_when_the_watchdog_applies_zero_torque(make_harness: Any) -> None:
    from smm_node_runtime import Level

    h = make_harness(clock_mode="realtime", command_timeout=0.02)
    h.wait_matched()
    h.spin_until(lambda: len(h.measurements) >= 3)
    assert h.sim.health().level is not Level.ERROR  # no command yet: waiting, not a fault
    h.send([0.1, -0.1], h.stamps()[-1])
    assert h.spin_until(lambda: h.sim.core.latency.count == 1)
    assert h.spin_until(lambda: h.sim.core.command_timeouts > 0)  # then no command any more
    health = h.sim.health()
    assert health.level is Level.ERROR
    assert "zero torque" in health.message
    assert health.values["command_timeouts"] == h.sim.core.command_timeouts
    assert h.spin_until(lambda: h.sim.diagnostics.level is Level.ERROR)  # sent at once, not a second later


def test_lockstep_start_gate_holds_step_0_until_every_publisher_has_its_subscribers(
    make_harness: Any,
) -> None:
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from smm_msgs_py.qos import subscription_qos_for_topic

    from smm_msgs_py import topics

    h = make_harness(**LOCKSTEP, **{"start.min_subscribers": 2})  # the peer reads joint_states once
    assert h.spin_until(lambda: h.sim.count_subscribers(f"/{topics.JOINT_STATES}") >= 1)
    h.spin_for(0.3)
    assert h.measurements == [] and h.sim.core.republished == 0, "step 0 must wait for the second reader"
    recorder = h.peer  # a second joint_states reader and a /clock reader: what a recorder adds
    second: list[Any] = []
    recorder.create_subscription(JointState, topics.JOINT_STATES, second.append, 10)
    h.spin_for(0.3)
    assert h.measurements == [], "/clock has no subscriber yet"
    recorder.create_subscription(Clock, "/clock", lambda _m: None, subscription_qos_for_topic(topics.CLOCK))
    assert h.spin_until(lambda: len(h.measurements) >= 1 and len(second) >= 1)
    assert h.stamps()[0] == 0
    h.send([0.0, 0.0], 0)
    assert h.spin_until(lambda: h.sim.core.steps == 1)
    result = h.sim.set_parameters([Parameter("start.min_subscribers", value=0)])[0]
    assert not result.successful and "start-up" in result.reason


def test_start_gate_parameter_has_a_range(make_harness: Any) -> None:
    from smm_sim.sim_node import SimParameterError

    with pytest.raises(SimParameterError, match="min_subscribers"):
        make_harness(**LOCKSTEP, **{"start.min_subscribers": -1})


def test_a_realtime_run_with_no_controller_exits_3_and_says_it_did_not_control(ros_domain_id: int) -> None:
    """Nothing answers (the test's own domain): every tick applies zero torque, whatever the machine."""
    from smm_bringup.graph_nodes import NodeSpec
    from smm_bringup.supervisor import resolve_executable

    spec = NodeSpec(
        "smm_sim",
        "smm_sim_node",
        "smm_sim_node",
        "smm_sim.sim_node:SimNode",
        parameters=(("clock_mode", "realtime"), ("max_steps", 50)),
    )
    result = subprocess.run(
        spec.command_line(resolve_executable(spec)), capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 3, result.stdout + result.stderr
    reason = "no torque command reached the plant: all 50 ticks applied zero torque"
    assert f"smm_sim_node: the run did not control: {reason}" in result.stderr
    assert f"run: did not control: {reason} (late 0 of 0 periods" in result.stderr


def test_a_realtime_run_missing_its_deadlines_did_not_control(
    make_harness: Any, capfd: pytest.CaptureFixture[str]
) -> None:
    """Only every other measurement is answered, so at least every other tick misses its deadline however
    fast or slow the machine; the command in force holds within its 0.5 s timeout."""
    from rclpy.parameter import Parameter

    h = make_harness(clock_mode="realtime", command_timeout=0.5, **{"verdict.settle_s": 0.0})
    h.wait_matched()
    answered: set[int] = set()

    def answer_even() -> bool:
        for stamp in h.stamps():
            if stamp // PERIOD_NS % 2 == 0 and stamp not in answered:
                answered.add(stamp)
                h.send([0.0, 0.0], stamp)
        return h.sim.core.judged_ticks >= 200

    assert h.spin_until(answer_even, timeout_s=30.0)
    assert h.sim.set_parameters([Parameter("max_steps", value=h.sim.core.steps + 1)])[0].successful
    assert h.spin_until(h.sim.done.done)
    core = h.sim.core
    assert core.late_judged >= core.judged_ticks // 2 - 1, core.statistics()
    reason = h.sim.run_verdict()
    assert reason is not None and "were late or not live, above the limit of 1 %" in reason
    closing = [line for line in "".join(capfd.readouterr()).splitlines() if "run: did not control:" in line]
    assert len(closing) == 1 and "late or not live" in closing[0] and "periods of 1 ms" in closing[0]


def test_a_lockstep_run_is_not_judged_by_deadlines(make_harness: Any) -> None:
    h = make_harness(**LOCKSTEP, max_steps=3)
    h.wait_matched()
    for step in range(3):
        h.send([0.0, 0.0], step * PERIOD_NS)
        assert h.spin_until(lambda step=step: h.sim.core.steps == step + 1)
    assert h.sim.done.done() and h.sim.run_verdict() is None
