"""td_node and reference_node in-process: outputs, stamps, duplicates, stale and bad input."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from controller_nodes.node_rig import measurement
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from smm_controller.reference import RampHoldReference, SineReference, StepReference
from smm_controller.reference_node import ReferenceClock, ReferenceNode
from smm_controller.td import TrackingDifferentiator, TrackingDifferentiatorConfig
from smm_controller.td_node import TdNode
from smm_msgs_py.conversions import joint_state_to_sample, msg_to_labelled, msg_to_reference
from smm_msgs_py.qos import diagnostic_qos
from std_msgs.msg import Float64MultiArray

from smm_msgs_py import topics

pytestmark = pytest.mark.ros

MS = 1_000_000


def bad_measurements(stamp_ns: int) -> dict[str, JointState]:
    """One raw measurement per kind of contract violation."""
    nan = measurement(stamp_ns)
    nan.position[0] = math.nan
    inf_effort = measurement(stamp_ns)
    inf_effort.effort[1] = math.inf
    short = measurement(stamp_ns)
    short.position = [0.1]
    unknown = measurement(stamp_ns)
    unknown.name = ["alpha", "gamma"]
    duplicate_name = measurement(stamp_ns)
    duplicate_name.name = ["alpha", "alpha"]
    bad_stamp = measurement(stamp_ns)
    bad_stamp.header.stamp.nanosec = 1_500_000_000
    return {
        "nan": nan,
        "inf_effort": inf_effort,
        "wrong_length": short,
        "unknown_joint": unknown,
        "duplicate_joint": duplicate_name,
        "bad_stamp": bad_stamp,
    }


def counter(message: Float64MultiArray, name: str) -> float:
    row = msg_to_labelled(message).row(name)
    assert row[0] == row[1]
    return float(row[0])


# ----------------------------------------------------------------------------------------------- TD


def test_td_node_answers_each_measurement_with_the_td_output_and_its_stamp(
    make_rig: Any, ros_context: Any
) -> None:
    rig = make_rig(TdNode(context=ros_context))
    out = rig.record(topics.JOINT_STATES_FILTERED)
    internals = rig.record("/td_node/internals", Float64MultiArray, diagnostic_qos())
    direct = TrackingDifferentiator(TrackingDifferentiatorConfig())
    positions = [(0.0, 0.0), (0.01, -0.02), (0.03, -0.01), (0.02, 0.05)]
    for k, position in enumerate(positions):
        rig.publish(topics.JOINT_STATES, measurement(k * MS, position))
        rig.wait_for(topics.JOINT_STATES_FILTERED, k + 1)
        sample = joint_state_to_sample(out[k], require_velocity=True)
        x1, x2 = direct.step(np.array(position), 1e-3)
        assert sample.stamp_ns == k * MS
        np.testing.assert_array_equal(sample.position, x1)
        np.testing.assert_array_equal(sample.velocity, x2)
    rig.wait_for("/td_node/internals", len(positions))
    last = msg_to_labelled(internals[-1])
    assert last.stamp_ns == 3 * MS
    np.testing.assert_array_equal(last.row("x2"), direct.internals["x2"])
    assert counter(internals[-1], "dropped_invalid") == 0


def test_td_duplicate_is_re_published_without_stepping_again(make_rig: Any, ros_context: Any) -> None:
    rig = make_rig(TdNode(context=ros_context))
    out = rig.record(topics.JOINT_STATES_FILTERED)
    internals = rig.record("/td_node/internals", Float64MultiArray, diagnostic_qos())
    direct = TrackingDifferentiator(TrackingDifferentiatorConfig())
    rig.publish(topics.JOINT_STATES, measurement(0, (0.0, 0.0)))
    rig.wait_for(topics.JOINT_STATES_FILTERED, 1)
    rig.publish(topics.JOINT_STATES, measurement(MS, (0.05, 0.05)))
    rig.wait_for(topics.JOINT_STATES_FILTERED, 2)
    # Same stamp, other values: a conflict, counted and not answered.
    rig.publish(topics.JOINT_STATES, measurement(MS, (0.06, 0.05)))
    # Re-transmission of stamp 1 ms: answered with the same message, not stepped.
    rig.publish(topics.JOINT_STATES, measurement(MS, (0.05, 0.05)))
    rig.wait_for(topics.JOINT_STATES_FILTERED, 3)
    assert out[2].header.stamp == out[1].header.stamp
    assert list(out[2].position) == list(out[1].position)
    assert list(out[2].velocity) == list(out[1].velocity)
    rig.publish(topics.JOINT_STATES, measurement(2 * MS, (0.07, 0.02)))
    rig.wait_for(topics.JOINT_STATES_FILTERED, 4)
    for position in ((0.0, 0.0), (0.05, 0.05), (0.07, 0.02)):
        x1, x2 = direct.step(np.array(position), 1e-3)
    sample = joint_state_to_sample(out[3], require_velocity=True)
    np.testing.assert_array_equal(sample.position, x1)
    np.testing.assert_array_equal(sample.velocity, x2)
    rig.settle()
    assert len(out) == 4  # the conflicting duplicate got no answer
    assert len(internals) == 3  # diagnostics go out once per stamp, never for a re-transmission
    assert counter(internals[-1], "duplicates_answered") == 1
    assert counter(internals[-1], "conflicting_duplicates") == 1


def test_td_stale_stamp_is_dropped_and_counted(make_rig: Any, ros_context: Any) -> None:
    rig = make_rig(TdNode(context=ros_context))
    out = rig.record(topics.JOINT_STATES_FILTERED)
    internals = rig.record("/td_node/internals", Float64MultiArray, diagnostic_qos())
    rig.publish(topics.JOINT_STATES, measurement(5 * MS))
    rig.wait_for(topics.JOINT_STATES_FILTERED, 1)
    rig.publish(topics.JOINT_STATES, measurement(4 * MS))
    rig.publish(topics.JOINT_STATES, measurement(6 * MS))
    rig.wait_for(topics.JOINT_STATES_FILTERED, 2)
    rig.settle()
    assert [joint_state_to_sample(m).stamp_ns for m in out] == [5 * MS, 6 * MS]
    rig.wait_for("/td_node/internals", 2)
    assert counter(internals[-1], "dropped_stale") == 1


def reference_node_without_lookahead(context: Any, **overrides: Any) -> ReferenceNode:
    """A reference node that answers each measurement with the reference of that measurement's stamp."""
    return ReferenceNode(context=context, parameter_overrides={"lookahead": 0, **overrides})


@pytest.mark.parametrize(
    "make_node",
    [TdNode, reference_node_without_lookahead],
    ids=["td_node", "reference_node"],
)
def test_bad_measurements_are_dropped_and_only_the_good_one_is_answered(
    make_rig: Any, ros_context: Any, make_node: Any
) -> None:
    node = make_node(context=ros_context)
    output_topic = topics.JOINT_STATES_FILTERED if isinstance(node, TdNode) else topics.REFERENCE
    rig = make_rig(node)
    out = rig.record(output_topic)
    bad = bad_measurements(3 * MS)
    for msg in bad.values():
        rig.publish(topics.JOINT_STATES, msg)
    rig.publish(topics.JOINT_STATES, measurement(7 * MS))
    rig.wait_for(output_topic, 1)
    rig.settle()
    assert len(out) == 1
    stamp = (
        joint_state_to_sample(out[0]).stamp_ns
        if isinstance(node, TdNode)
        else msg_to_reference(out[0]).stamp_ns
    )
    assert stamp == 7 * MS
    assert node.counters.dropped_invalid == len(bad)
    assert node.last_answered_stamp_ns == 7 * MS


def test_td_filter_factor_below_the_control_period_is_rejected(make_rig: Any, ros_context: Any) -> None:
    node = TdNode(
        context=ros_context, parameter_overrides={"control_period": 0.002, "td.filter_factor": [0.002, 0.002]}
    )
    make_rig(node)
    (result,) = node.set_parameters([Parameter("td.filter_factor", value=[0.001, 0.003])])
    assert not result.successful
    assert "td.filter_factor" in result.reason and "control_period" in result.reason
    (result,) = node.set_parameters([Parameter("control_period", value=0.001)])
    assert not result.successful and "read-only" in result.reason


def test_td_refuses_to_start_with_invalid_initial_parameters(ros_context: Any) -> None:
    with pytest.raises(ValueError, match="speed must be > 0"):
        TdNode(context=ros_context, parameter_overrides={"td.speed": [-1.0, 1.0]})


def test_td_gain_change_acts_on_the_next_step_and_keeps_the_state(make_rig: Any, ros_context: Any) -> None:
    node = TdNode(context=ros_context)
    rig = make_rig(node)
    td_before = node.td
    out = rig.record(topics.JOINT_STATES_FILTERED)
    direct = TrackingDifferentiator(TrackingDifferentiatorConfig())
    positions = [(0.0, 0.0), (0.01, -0.02), (0.03, -0.03), (0.1, -0.08), (0.15, -0.1)]
    for k in range(3):
        rig.publish(topics.JOINT_STATES, measurement(k * MS, positions[k]))
        rig.wait_for(topics.JOINT_STATES_FILTERED, k + 1)
        direct.step(np.array(positions[k]), 1e-3)
    new_config = TrackingDifferentiatorConfig(speed=(50.0, 60.0), filter_factor=(0.01, 0.02))
    results = node.set_parameters(
        [Parameter("td.speed", value=[50.0, 60.0]), Parameter("td.filter_factor", value=[0.01, 0.02])]
    )
    assert all(r.successful for r in results)
    assert node.td_parameters.config == new_config
    assert node.td is td_before and node.td.config == new_config
    # Documented effect: same TD, new gains from the next sample; x1 and x2 carry on.
    direct.reconfigure(new_config)
    restarted = TrackingDifferentiator(new_config)
    for k in (3, 4):
        rig.publish(topics.JOINT_STATES, measurement(k * MS, positions[k]))
        rig.wait_for(topics.JOINT_STATES_FILTERED, k + 1)
        x1, x2 = direct.step(np.array(positions[k]), 1e-3)
        sample = joint_state_to_sample(out[k], require_velocity=True)
        np.testing.assert_array_equal(sample.position, x1)
        np.testing.assert_array_equal(sample.velocity, x2)
        # A rebuilt TD would restart at the sample with x2 = 0.
        assert not np.allclose(sample.velocity, restarted.step(np.array(positions[k]), 1e-3)[1])


# ---------------------------------------------------------------------------------------- reference


def test_reference_clock_counts_from_the_first_stamp_in_exact_integers() -> None:
    clock = ReferenceClock()
    assert clock.first_stamp_ns is None
    first = 2**62 + 1  # beyond float precision: the difference must be taken in integers
    assert clock.time_s(first) == 0.0
    assert clock.first_stamp_ns == first
    assert clock.time_s(first + 1_700 * MS + 1) == (1_700 * MS + 1) / 1e9
    assert clock.time_s(first - MS) == -1e-3  # an earlier stamp later on does not move t = 0
    assert clock.first_stamp_ns == first


def test_reference_clock_announces_its_origin_once() -> None:
    notes: list[str] = []
    clock = ReferenceClock(notes.append)
    clock.time_s(5 * MS)
    clock.time_s(6 * MS)
    assert notes == [f"reference t = 0 s at measurement stamp {5 * MS} ns"]


def test_reference_is_sampled_at_the_time_since_the_first_stamp(make_rig: Any, ros_context: Any) -> None:
    # Gaps of up to 1.45 s: allowed by a wider stamp window (the default refuses more than 100 periods).
    rig = make_rig(reference_node_without_lookahead(ros_context, **{"stamp.max_ahead_periods": 2000}))
    out = rig.record(topics.REFERENCE)
    first = 10**15 + 123  # any epoch: t counts from the first measurement
    stamps = [first, first + MS, first + 250 * MS, first + 1_700 * MS]
    for k, stamp in enumerate(stamps):
        rig.publish(topics.JOINT_STATES, measurement(stamp))
        rig.wait_for(topics.REFERENCE, k + 1)
    generator = SineReference()
    for stamp, msg in zip(stamps, out, strict=True):
        parsed = msg_to_reference(msg)
        assert parsed.stamp_ns == stamp
        np.testing.assert_array_equal(parsed.values, generator.evaluate((stamp - first) / 1e9))


def test_reference_kind_and_generator_parameters_act_on_the_next_measurement(
    make_rig: Any, ros_context: Any
) -> None:
    node = reference_node_without_lookahead(ros_context, **{"kind": "step", "step.amplitude": [0.5, 0.25]})
    rig = make_rig(node)
    out = rig.record(topics.REFERENCE)
    rig.publish(topics.JOINT_STATES, measurement(0))
    rig.wait_for(topics.REFERENCE, 1)
    np.testing.assert_array_equal(msg_to_reference(out[0]).values, StepReference((0.5, 0.25)).evaluate(0.0))
    results = node.set_parameters(
        [
            Parameter("kind", value="ramp_hold"),
            Parameter("ramp_hold.target", value=[0.4, -0.4]),
            Parameter("ramp_hold.ramp_time", value=0.5),
        ]
    )
    assert all(r.successful for r in results)
    rig.publish(topics.JOINT_STATES, measurement(100 * MS))
    rig.wait_for(topics.REFERENCE, 2)
    expected = RampHoldReference(target=(0.4, -0.4), ramp_time=0.5).evaluate(0.1)
    np.testing.assert_array_equal(msg_to_reference(out[1]).values, expected)


@pytest.mark.parametrize(("lookahead", "period_ms"), [(1, 1), (2, 1), (1, 5)])
def test_reference_is_published_lookahead_periods_ahead(
    make_rig: Any, ros_context: Any, lookahead: int, period_ms: int
) -> None:
    node = ReferenceNode(
        context=ros_context,
        parameter_overrides={"lookahead": lookahead, "control_period": period_ms / 1e3},
    )
    rig = make_rig(node)
    out = rig.record(topics.REFERENCE)
    period = period_ms * MS
    first = 10**12 + 7
    rig.publish(topics.JOINT_STATES, measurement(first))
    # The first measurement: every stamp from the first to `lookahead` periods ahead.
    rig.wait_for(topics.REFERENCE, lookahead + 1)
    rig.publish(topics.JOINT_STATES, measurement(first))  # re-transmission: the same answer again
    rig.wait_for(topics.REFERENCE, 2 * (lookahead + 1))
    rig.publish(topics.JOINT_STATES, measurement(first + period))
    rig.wait_for(topics.REFERENCE, 2 * (lookahead + 1) + 1)
    rig.settle()
    first_answer = [first + j * period for j in range(lookahead + 1)]
    expected_stamps = [*first_answer, *first_answer, first + (lookahead + 1) * period]
    parsed = [msg_to_reference(msg) for msg in out]
    assert [reference.stamp_ns for reference in parsed] == expected_stamps
    generator = SineReference()
    for reference in parsed:
        np.testing.assert_array_equal(
            reference.values, generator.evaluate((reference.stamp_ns - first) / 1e9)
        )
    assert node.counters.duplicates_answered == 1


def test_reference_node_refuses_a_negative_lookahead(ros_context: Any) -> None:
    with pytest.raises(ValueError, match=r"lookahead out of range\. Min: 0"):
        ReferenceNode(context=ros_context, parameter_overrides={"lookahead": -1})


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("kind", "square", "kind must be one of"),
        ("sine.angular_frequency", -1.0, "sine.angular_frequency out of range Min: 0.0"),
        ("sine.amplitude", [1.0, 2.0, 3.0], r"sine.amplitude must have 2 values"),
        ("ramp_hold.profile", "cubic", "profile must be"),
    ],
)
def test_invalid_reference_parameters_are_rejected_with_the_reason(
    make_rig: Any, ros_context: Any, name: str, value: Any, reason: str
) -> None:
    node = ReferenceNode(context=ros_context)
    make_rig(node)
    before = node.generator
    (result,) = node.set_parameters([Parameter(name, value=value)])
    assert not result.successful
    assert reason.replace("\\", "") in result.reason or __import__("re").search(reason, result.reason)
    assert node.generator == before
