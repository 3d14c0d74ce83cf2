"""Issue 12 on a running controller node: no input stops control, none commands an absurd torque.

The node runs the fused chain with the internal reference (its only input is ``joint_states``), as
``smm-launch`` starts it. Each message is published and the node spun until it has taken it in
(``node.inputs``), so the order of arrival is the order sent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from controller_nodes.node_rig import Rig, measurement
from diagnostic_msgs.msg import DiagnosticArray
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import JointState
from smm_controller.controller_node import ControllerNode
from smm_controller.limits import DEFAULT_POSITION_LIMIT, DEFAULT_TORQUE_LIMIT
from smm_msgs_py.conversions import msg_to_torque
from smm_msgs_py.qos import diagnostic_qos
from smm_msgs_py.topics import DIAGNOSTICS

from smm_msgs_py import topics
from smm_node_runtime import Level

pytestmark = pytest.mark.ros

MS = 1_000_000
HOUR_NS = 3_600 * 10**9
RESYNC_SAMPLES = 5
RECOVERY_SAMPLES = 80
"""Valid samples sent after a burst; control must be back well within them (bound: see the test)."""


def fused_node(context: Any, **overrides: Any) -> ControllerNode:
    return ControllerNode(
        context=context,
        parameter_overrides={
            "chain": "internal",
            "reference_source": "internal",
            "stamp.resync_samples": RESYNC_SAMPLES,
            **overrides,
        },
    )


def send(rig: Rig, node: ControllerNode, msg: JointState) -> None:
    """Publish ``msg`` and spin until the node has taken it in (answered, dropped or refused)."""
    before = node.inputs
    rig.publish(topics.JOINT_STATES, msg)
    assert rig.spin_until(lambda: node.inputs > before), "the node never took the message in"


def raw(stamp_ns: int, names: list[str], position: list[float]) -> JointState:
    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    msg.name = names
    msg.position = position
    return msg


# ---------------------------------------------------------------------------------- adversarial burst


@dataclass(frozen=True)
class Sent:
    """One message of a burst and whether its content is valid (finite, complete, within the range)."""

    msg: JointState
    stamp_ns: int
    valid: bool


_KINDS = (
    "valid",
    "valid",
    "valid",
    "nan",
    "inf",
    "short",
    "unknown_name",
    "past",
    "future_hour",
    "ahead_of_clock",
    "duplicate",
    "conflicting_duplicate",
    "huge",
    "beyond_stops",
    "jump",
)


class Burst:
    """Builds the messages of a burst from drawn kinds; every invalid message gets a stamp of its own."""

    def __init__(self) -> None:
        self.stamp_ns = 10 * MS
        self.position = (0.0, 0.0)
        self.unique = 0
        self.last_valid: Sent | None = None

    def _unique(self, base: int) -> int:
        self.unique += 1
        return base + 100 + self.unique  # never a multiple of a period: used by no valid message

    def next_valid(self, step: tuple[float, float]) -> Sent:
        self.stamp_ns += MS
        self.position = (
            float(np.clip(self.position[0] + step[0], -1.2, 1.2)),
            float(np.clip(self.position[1] + step[1], -1.2, 1.2)),
        )
        sent = Sent(measurement(self.stamp_ns, self.position, None), self.stamp_ns, True)
        self.last_valid = sent
        return sent

    def make(self, kind: str, step: tuple[float, float], big: float) -> Sent:
        names = ["alpha", "beta"]
        if kind == "valid":
            return self.next_valid(step)
        if kind in ("duplicate", "conflicting_duplicate") and self.last_valid is not None:
            stamp = self.last_valid.stamp_ns
            if kind == "duplicate":
                return Sent(measurement(stamp, self.position, None), stamp, True)
            other = (self.position[0] + 0.01, self.position[1])
            return Sent(measurement(stamp, other, None), stamp, True)
        if kind == "past":
            stamp = self._unique(max(0, self.stamp_ns - 50 * MS))
            return Sent(measurement(stamp, self.position, None), stamp, True)
        if kind == "future_hour":
            stamp = self._unique(self.stamp_ns + HOUR_NS)
            return Sent(measurement(stamp, self.position, None), stamp, True)
        if kind == "ahead_of_clock":
            stamp = self._unique(2 * 10**18)  # year 2033: ahead of the node clock
            return Sent(measurement(stamp, self.position, None), stamp, True)
        if kind == "jump":  # within the range, but far from the last position
            stamp = self._unique(self.stamp_ns)
            jumped = (-self.position[0] if abs(self.position[0]) > 0.5 else 1.2, self.position[1])
            return Sent(measurement(stamp, jumped, None), stamp, True)
        stamp = self._unique(self.stamp_ns)
        if kind == "nan":
            return Sent(raw(stamp, names, [math.nan, 0.0]), stamp, False)
        if kind == "inf":
            return Sent(raw(stamp, names, [0.0, -math.inf]), stamp, False)
        if kind == "short":
            return Sent(raw(stamp, names[:1], [0.1]), stamp, False)
        if kind == "unknown_name":
            return Sent(raw(stamp, ["gamma", "beta"], [0.1, 0.1]), stamp, False)
        if kind == "huge":
            return Sent(raw(stamp, names, [big, 0.2]), stamp, False)
        # beyond_stops: finite, but beyond the stops plus margin (the (100, 100) rad)
        return Sent(raw(stamp, names, [100.0, 100.0]), stamp, False)


steps = st.tuples(
    st.floats(min_value=-0.05, max_value=0.05, allow_subnormal=False),
    st.floats(min_value=-0.05, max_value=0.05, allow_subnormal=False),
)
bursts = st.lists(
    st.tuples(
        st.sampled_from(_KINDS),
        steps,
        st.sampled_from([1e300, -1e300, 1e6, 2.0 * DEFAULT_POSITION_LIMIT[0]]),
    ),
    min_size=5,
    max_size=40,
)


@settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(burst=bursts)
def test_no_input_sequence_stops_control_or_commands_an_absurd_torque(
    ros_context: Any, burst: list[tuple[str, tuple[float, float], float]]
) -> None:
    node = fused_node(ros_context)
    rig = Rig(ros_context, [node])
    try:
        torques = rig.record(topics.TORQUE_COMMAND)
        maker = Burst()
        sent = [maker.next_valid((0.0, 0.0))]
        sent += [maker.make(kind, step, big) for kind, step, big in burst]
        for item in sent:
            send(rig, node, item.msg)
        after = [maker.next_valid((0.001, -0.001)) for _ in range(RECOVERY_SAMPLES)]
        for item in after:
            send(rig, node, item.msg)
        rig.settle(0.05)

        commands = [msg_to_torque(msg) for msg in torques]
        valid_stamps = {item.stamp_ns for item in [*sent, *after] if item.valid}
        by_stamp: dict[int, list[float]] = {}
        for command in commands:
            # no command exceeds the torque limit
            assert np.all(np.abs(command.values) <= DEFAULT_TORQUE_LIMIT), command
            # no command answers an invalid measurement
            assert command.stamp_ns in valid_stamps, f"command for invalid stamp {command.stamp_ns}"
            # a stamp is answered once; only an identical re-transmission re-publishes that answer
            previous = by_stamp.setdefault(command.stamp_ns, list(command.values))
            assert previous == list(command.values)
        # after the burst, valid measurements are answered again within a bounded number of periods:
        # a resync takes RESYNC_SAMPLES; a step from the last accepted position (at most 2.4 rad away)
        # becomes plausible after 2.4 rad / (100 rad/s) = 24 periods.
        answered = {command.stamp_ns for command in commands}
        bound = RESYNC_SAMPLES + 25
        resumed = [k for k, item in enumerate(after) if item.stamp_ns in answered]
        assert resumed, "control never came back after the burst"
        assert resumed[0] <= bound, f"control came back only after {resumed[0]} samples"
        assert resumed == list(range(resumed[0], RECOVERY_SAMPLES)), "control stopped again"
    finally:
        rig.close()


# ------------------------------------------------------------------------------- the cases


def test_one_measurement_an_hour_ahead_is_refused_and_control_goes_on(
    make_rig: Any, ros_context: Any
) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    for k in range(1, 4):
        send(rig, node, measurement(k * MS, (0.0, 0.0), None))
    send(rig, node, measurement(3 * MS + HOUR_NS, (0.0, 0.0), None))
    for k in range(4, 10):
        send(rig, node, measurement(k * MS, (0.0, 0.0), None))
    rig.settle(0.05)
    assert [msg_to_torque(msg).stamp_ns for msg in torques] == [k * MS for k in range(1, 10)]
    assert node.counters.dropped_ahead == 1
    assert node.counters.dropped_stale == 0
    assert node.last_answered_stamp_ns == 9 * MS


def test_a_simulator_restart_is_recognised_and_control_resumes_with_a_warning(
    make_rig: Any, ros_context: Any
) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    for k in range(1000, 1010):
        send(rig, node, measurement(k * MS, (0.0, 0.0), None))
    for k in range(10):  # the restarted simulator counts from 0 again
        send(rig, node, measurement(k * MS, (0.0, 0.0), None))
    rig.settle(0.05)
    stamps = [msg_to_torque(msg).stamp_ns for msg in torques]
    assert stamps[:10] == [k * MS for k in range(1000, 1010)]
    assert stamps[10:] == [k * MS for k in range(RESYNC_SAMPLES - 1, 10)]
    assert node.counters.time_jumps == 1
    assert node.counters.dropped_stale == RESYNC_SAMPLES - 1


def test_a_conflicting_duplicate_is_counted_and_not_answered(make_rig: Any, ros_context: Any) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    send(rig, node, measurement(MS, (0.1, 0.0), None))
    send(rig, node, measurement(MS, (0.1, 0.0), None))  # lockstep re-transmission: re-answered
    send(rig, node, measurement(MS, (0.2, 0.0), None))  # same stamp, other values: refused
    rig.settle(0.05)
    assert len(torques) == 2
    assert list(torques[0].data) == list(torques[1].data)
    assert node.counters.duplicates_answered == 1
    assert node.counters.conflicting_duplicates == 1


def test_the_torque_limit_clamps_and_shows_in_the_internals(make_rig: Any, ros_context: Any) -> None:
    node = fused_node(ros_context, **{"output.torque_limit": [0.5, 0.5]})
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    internals = rig.record(topics.CONTROLLER_INTERNALS)
    for k in range(1, 4):
        send(rig, node, measurement(k * MS, (-0.3, 0.3), None))
    rig.wait_for(topics.CONTROLLER_INTERNALS, 3)
    assert all(np.all(np.abs(msg_to_torque(msg).values) <= 0.5) for msg in torques)
    assert node.limiter.clamps >= 1
    from smm_msgs_py.conversions import msg_to_labelled

    labelled = msg_to_labelled(internals[-1])
    assert labelled.row("limiter.clamps")[0] == node.limiter.clamps
    assert np.any(np.abs(labelled.row("limiter.tau_unlimited")) > 0.5)


# ------------------------------------------------------------------------------------ /diagnostics


def statuses(messages: list[DiagnosticArray], name: str) -> list[Any]:
    return [status for array in messages for status in array.status if status.name == name]


def test_the_controller_status_is_ok_in_use_and_error_when_every_input_is_refused(
    make_rig: Any, ros_context: Any
) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    seen = rig.record(DIAGNOSTICS, DiagnosticArray, diagnostic_qos())
    rig.record(topics.TORQUE_COMMAND)
    assert rig.spin_until(lambda: bool(statuses(seen, "/controller_node")))
    for k in range(1, 50):
        send(rig, node, measurement(k * MS, (0.0, 0.0), None))
    first = statuses(seen, "/controller_node")[0]
    assert {kv.key for kv in first.values} >= {
        "loop_rate_hz",
        "deadline_misses",
        "dropped_invalid",
        "dropped_stale",
        "dropped_ahead",
        "dropped_implausible",
        "clamps",
        "last_error",
    }
    # The forced fault: for over a period, every measurement is invalid (NaN): control has stopped.
    nan = 0

    def flood() -> bool:
        nonlocal nan
        nan += 1
        send(rig, node, raw(100 * MS + nan, ["alpha", "beta"], [math.nan, 0.0]))
        return node.diagnostics.level is Level.ERROR

    assert rig.spin_until(flood, timeout_s=10.0)
    error = statuses(seen, "/controller_node")[-1]
    assert error.level == bytes([Level.ERROR])
    assert "control stopped" in error.message
    assert "NaN" in {kv.key: kv.value for kv in error.values}[
        "last_error"
    ] or "finite" in error.message + str(error.values)


def test_a_refused_input_raises_the_status_to_warn_at_once(make_rig: Any, ros_context: Any) -> None:
    # A 50 ms period: a slow first step on a busy machine must not be a deadline miss (itself a WARN).
    period = 0.05
    node = fused_node(ros_context, control_period=period, **{"td.filter_factor": [period, period]})
    rig = make_rig(node)
    seen = rig.record(DIAGNOSTICS, DiagnosticArray, diagnostic_qos())
    step_ns = round(period * 1e9)
    send(rig, node, measurement(step_ns, (0.0, 0.0), None))
    assert rig.spin_until(lambda: bool(statuses(seen, "/controller_node")))
    assert statuses(seen, "/controller_node")[-1].level == bytes([Level.OK])
    count = len(statuses(seen, "/controller_node"))
    send(rig, node, measurement(2 * step_ns, (100.0, 100.0), None))

    def warned() -> list[Any]:
        later = statuses(seen, "/controller_node")[count:]
        return [status for status in later if status.level == bytes([Level.WARN])]

    assert rig.spin_until(lambda: bool(warned()), timeout_s=0.5)  # at once, not at the next period
    assert "dropped_implausible" in warned()[0].message


# ------------------------------------------------------------------------------------------ parameters


def test_scalar_parameters_with_a_bound_carry_a_ros_range(ros_context: Any) -> None:
    node = fused_node(ros_context)
    try:
        expected = {
            "control_period": (0.0, 1.0),
            "stamp.max_ahead_periods": (1, 100_000),
            "stamp.clock_tolerance": (1e-3, 3600.0),
            "switch_idle_time": (0.0, math.inf),
            "model.I11": (0.0, math.inf),
            "fleso.grid_points": (3, 2**63 - 1),
        }
        for name, (low, high) in expected.items():
            descriptor = node.describe_parameter(name)
            ranges = (
                descriptor.integer_range
                if descriptor.type == ParameterType.PARAMETER_INTEGER
                else descriptor.floating_point_range
            )
            assert len(ranges) == 1, name
            assert (ranges[0].from_value, ranges[0].to_value) == (low, high), name
        (result,) = node.set_parameters([Parameter("stamp.max_ahead_periods", value=0)])
        assert not result.successful and "stamp.max_ahead_periods" in result.reason
    finally:
        node.destroy_node()


def test_setting_an_unknown_parameter_over_the_service_names_it(make_rig: Any, ros_context: Any) -> None:
    node = fused_node(ros_context)
    rig = make_rig(node)
    client = AsyncParameterClient(rig.probe, "controller_node")
    assert client.wait_for_services(timeout_sec=10.0)
    future = client.set_parameters([Parameter("output.torque_limt", value=[1.0, 1.0])])
    assert rig.spin_until(future.done)
    (result,) = future.result().results
    assert not result.successful
    assert "output.torque_limt" in result.reason
