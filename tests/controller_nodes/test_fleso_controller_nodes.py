"""fleso_node and controller_node in-process: stamp matching, outputs, duplicates, bad input, parameters."""

from __future__ import annotations

import array
import math
import re
import time
from typing import Any

import numpy as np
import pytest
from controller_nodes.node_rig import filtered, measurement
from rclpy.parameter import Parameter
from smm_controller.baselines import NPDConfig, NPDController, PIDConfig, PIDController
from smm_controller.controller_node import ControllerNode
from smm_controller.fleso import FLESO, FLESOConfig
from smm_controller.fleso_node import COMMAND_FALLBACK_LATE_ROW, FlesoNode
from smm_controller.fpdeso import FPDESOConfig, FPDESOController
from smm_controller.fuzzy_pd import FuzzyPDConfig
from smm_controller.model import NominalModel
from smm_controller.reference import SineReference
from smm_msgs_py.conversions import (
    labelled_to_msg,
    msg_to_labelled,
    msg_to_torque,
    reference_to_msg,
    torque_to_msg,
)
from smm_msgs_py.layouts import DISTURBANCE_ESTIMATE_ROWS, OBSERVER_STATE_ROWS
from smm_msgs_py.qos import diagnostic_qos
from std_msgs.msg import Float64MultiArray

from smm_dynamics import SMMParameters
from smm_msgs_py import topics

pytestmark = pytest.mark.ros

MS = 1_000_000
DT = 1e-3
INTERNALS_TOPIC_OF_FLESO = "/fleso_node/internals"


def estimate_msg(
    stamp_ns: int, xi: tuple[float, float] = (0.2, -0.1), velocity: tuple[float, float] = (0.3, 0.4)
) -> Float64MultiArray:
    """disturbance_estimate: xi~ (N m) and the observer velocity x2^ (rad/s; default = filtered()'s)."""
    return labelled_to_msg([xi, velocity], DISTURBANCE_ESTIMATE_ROWS, stamp_ns)


def reference_msg(stamp_ns: int) -> Float64MultiArray:
    return reference_to_msg(SineReference().evaluate(stamp_ns / 1e9), stamp_ns)


def with_data(msg: Float64MultiArray, values: list[float]) -> Float64MultiArray:
    msg.data = array.array("d", values)
    return msg


def bad_arrays(good: Any, stamp_ns: int) -> dict[str, Float64MultiArray]:
    """One Float64MultiArray per kind of contract violation, built from a good one."""
    nan = good(stamp_ns)
    nan.data[0] = math.nan
    short = with_data(good(stamp_ns), [0.0])
    wrong_label = good(stamp_ns)
    wrong_label.layout.dim[-2].label = "joint:alpha,gamma"
    no_stamp = good(stamp_ns)
    no_stamp.layout.dim.pop()
    offset = good(stamp_ns)
    offset.layout.data_offset = 1
    return {"nan": nan, "short": short, "wrong_label": wrong_label, "no_stamp": no_stamp, "offset": offset}


def bad_filtered(stamp_ns: int) -> dict[str, Any]:
    nan = filtered(stamp_ns)
    nan.velocity[1] = math.nan
    no_velocity = filtered(stamp_ns)
    no_velocity.velocity = []
    unknown = filtered(stamp_ns)
    unknown.name = ["beta", "gamma"]
    return {"nan": nan, "no_velocity": no_velocity, "unknown_joint": unknown}


# --------------------------------------------------------------------------------------------- FLESO


def test_fleso_node_matches_filtered_position_and_applied_torque_by_stamp(
    make_rig: Any, ros_context: Any
) -> None:
    rig = make_rig(FlesoNode(context=ros_context))
    estimates = rig.record(topics.DISTURBANCE_ESTIMATE)
    observer = rig.record(topics.OBSERVER_STATE)
    direct = FLESO(FLESOConfig(), SMMParameters())
    inputs = [((0.0, 0.0), (0.0, 0.0)), ((0.001, 0.002), (0.5, -0.3)), ((0.003, 0.001), (0.7, -0.1))]
    for k, (position, torque) in enumerate(inputs):
        rig.publish(topics.JOINT_STATES_FILTERED, filtered(k * MS, position))
        rig.settle(0.05)
        assert len(estimates) == k  # half a pair is never answered
        rig.publish(topics.JOINT_STATES, measurement(k * MS, (9.0, 9.0), torque))
        rig.wait_for(topics.DISTURBANCE_ESTIMATE, k + 1)
        expected = direct.step(np.array(position), np.array(torque), DT)
        parsed = msg_to_labelled(estimates[k], expected_rows=DISTURBANCE_ESTIMATE_ROWS)
        assert parsed.stamp_ns == k * MS
        np.testing.assert_array_equal(parsed.row("xi_tilde"), expected)
    rig.wait_for(topics.OBSERVER_STATE, len(inputs))
    state = msg_to_labelled(observer[-1], expected_rows=OBSERVER_STATE_ROWS)
    for row in OBSERVER_STATE_ROWS:
        np.testing.assert_array_equal(state.row(row), direct.internals[row])


def test_fleso_bad_input_on_either_subscription_is_dropped(make_rig: Any, ros_context: Any) -> None:
    node = FlesoNode(context=ros_context)
    rig = make_rig(node)
    estimates = rig.record(topics.DISTURBANCE_ESTIMATE)
    short_effort = measurement(2 * MS)
    short_effort.effort = [0.5]  # an effort is optional, but if present it has one value per joint
    nan_effort = measurement(2 * MS)
    nan_effort.effort[0] = math.nan
    bad = [(topics.JOINT_STATES_FILTERED, m) for m in bad_filtered(2 * MS).values() if m.velocity]
    bad += [(topics.JOINT_STATES, short_effort), (topics.JOINT_STATES, nan_effort)]
    for topic, msg in bad:
        rig.publish(topic, msg)
    # A good half pairs with nothing bad: stamp 2 ms has one good input only and is never answered.
    rig.publish(topics.JOINT_STATES_FILTERED, filtered(2 * MS))
    rig.publish(topics.JOINT_STATES_FILTERED, filtered(3 * MS))
    rig.publish(topics.JOINT_STATES, measurement(3 * MS))
    rig.wait_for(topics.DISTURBANCE_ESTIMATE, 1)
    rig.settle()
    assert [msg_to_labelled(m).stamp_ns for m in estimates] == [3 * MS]
    assert node.counters.dropped_invalid == len(bad)
    assert node.counters.dropped_unmatched == 1


def test_fleso_duplicate_re_publishes_the_estimate_without_stepping(make_rig: Any, ros_context: Any) -> None:
    node = FlesoNode(context=ros_context)
    rig = make_rig(node)
    estimates = rig.record(topics.DISTURBANCE_ESTIMATE)
    direct = FLESO(FLESOConfig(), SMMParameters())
    for k in range(2):
        rig.publish(topics.JOINT_STATES_FILTERED, filtered(k * MS, (0.001 * k, 0.0)))
        rig.publish(topics.JOINT_STATES, measurement(k * MS, effort=(1.0, -1.0)))
        rig.wait_for(topics.DISTURBANCE_ESTIMATE, k + 1)
        direct.step(np.array((0.001 * k, 0.0)), np.array((1.0, -1.0)), DT)
    rig.publish(topics.JOINT_STATES, measurement(MS, effort=(50.0, 50.0)))  # same stamp, other values
    rig.publish(topics.JOINT_STATES, measurement(MS, effort=(1.0, -1.0)))  # an identical re-transmission
    rig.wait_for(topics.DISTURBANCE_ESTIMATE, 3)
    assert list(estimates[2].data) == list(estimates[1].data)
    assert estimates[2].layout.dim[-1].label == estimates[1].layout.dim[-1].label
    rig.publish(topics.JOINT_STATES_FILTERED, filtered(2 * MS, (0.004, 0.001)))
    rig.publish(topics.JOINT_STATES, measurement(2 * MS, effort=(1.0, -1.0)))
    rig.wait_for(topics.DISTURBANCE_ESTIMATE, 4)
    rig.settle()
    assert len(estimates) == 4  # the conflicting duplicate got no answer
    expected = direct.step(np.array((0.004, 0.001)), np.array((1.0, -1.0)), DT)
    np.testing.assert_array_equal(msg_to_labelled(estimates[3]).row("xi_tilde"), expected)
    assert node.counters.duplicates_answered == 1
    assert node.counters.conflicting_duplicates == 1


def test_fleso_gain_change_is_validated_and_reconfigures_it(make_rig: Any, ros_context: Any) -> None:
    node = FlesoNode(context=ros_context)
    make_rig(node)
    observer = node.fleso
    (rejected,) = node.set_parameters([Parameter("fleso.w0", value=[-20.0, 28.0])])
    assert not rejected.successful and "w0 must be > 0" in rejected.reason
    (rejected,) = node.set_parameters([Parameter("model.I55", value=0.0)])
    assert not rejected.successful and "I55 must be > 0" in rejected.reason
    assert node.fleso.config == FLESOConfig()
    (accepted,) = node.set_parameters([Parameter("fleso.w0", value=[30.0, 40.0])])
    assert accepted.successful
    assert node.fleso is observer and node.fleso.config == FLESOConfig(w0=(30.0, 40.0))
    (accepted,) = node.set_parameters([Parameter("model.I55", value=0.08)])
    assert accepted.successful
    assert node.fleso is observer and node.fleso.model is NominalModel.shared(SMMParameters(I55=0.08))


def fleso_step(rig: Any, k: int, position: Any, effort: Any | None) -> np.ndarray:
    """Feed stamp k (filtered position, measurement with or without effort); return the estimate."""
    raw = measurement(k * MS, (9.0, 9.0), effort if effort is not None else (0.0, 0.0))
    if effort is None:
        raw.effort = []
    rig.publish(topics.JOINT_STATES_FILTERED, filtered(k * MS, position))
    rig.publish(topics.JOINT_STATES, raw)
    estimates = rig.wait_for(topics.DISTURBANCE_ESTIMATE, k + 1)
    estimate = msg_to_labelled(estimates[k], expected_rows=DISTURBANCE_ESTIMATE_ROWS)
    assert estimate.stamp_ns == k * MS
    return estimate.row("xi_tilde")


def test_fleso_gain_change_keeps_the_disturbance_estimate(make_rig: Any, ros_context: Any) -> None:
    # A fast fixed bandwidth (w = 60 rad/s) converges within the 300 steps; at rest at q under
    # tau = G(q) + d the estimate settles at d.
    fast = {"fleso.w0": [60.0, 60.0], "fleso.k_w": [0.0, 0.0]}
    node = FlesoNode(context=ros_context, parameter_overrides=fast)
    rig = make_rig(node)
    rig.record(topics.DISTURBANCE_ESTIMATE)
    q = (0.3, 0.5)
    disturbance = np.array([0.4, -0.3])
    *_, g0, g1 = NominalModel.shared(SMMParameters()).bias(q[0], q[1], 0.0, 0.0)
    torque = np.array([g0, g1]) + disturbance
    direct = FLESO(FLESOConfig(w0=(60.0, 60.0), k_w=(0.0, 0.0)), SMMParameters())
    steps = 300
    for k in range(steps):
        estimate = fleso_step(rig, k, q, torque)
        direct.step(np.array(q), torque, DT)
    np.testing.assert_allclose(estimate, disturbance, rtol=0, atol=1e-4)
    (accepted,) = node.set_parameters([Parameter("fleso.w0", value=[25.0, 30.0])])
    assert accepted.successful
    direct.reconfigure(FLESOConfig(w0=(25.0, 30.0), k_w=(0.0, 0.0)))
    after = fleso_step(rig, steps, q, torque)
    np.testing.assert_array_equal(after, direct.step(np.array(q), torque, DT))
    # No bump: the estimate moves by far less than the disturbance (a rebuilt observer would give 0).
    assert np.max(np.abs(after - estimate)) < 1e-4


def command_msg(stamp_ns: int, tau: tuple[float, float]) -> Float64MultiArray:
    return torque_to_msg(np.array(tau), stamp_ns)


def commands(k: int) -> tuple[float, float]:
    return (0.5 + 0.1 * k, -0.2 - 0.05 * k)


POSITIONS = [(0.0, 0.0), (0.001, 0.002), (0.003, 0.001), (0.004, -0.001), (0.006, -0.002), (0.007, -0.004)]


def publish_command(rig: Any, node: FlesoNode, k: int) -> None:
    """Publish the command answering stamp k and wait until the node holds it (as in lockstep)."""
    rig.publish(topics.TORQUE_COMMAND, command_msg(k * MS, commands(k)))
    assert rig.spin_until(lambda: node.newest_command_stamp_ns == k * MS)


def test_fleso_without_effort_uses_the_command_answering_the_previous_measurement(
    make_rig: Any, ros_context: Any
) -> None:
    node = FlesoNode(context=ros_context)
    rig = make_rig(node)
    rig.record(topics.DISTURBANCE_ESTIMATE)
    rig.record(INTERNALS_TOPIC_OF_FLESO, Float64MultiArray, diagnostic_qos())
    direct = FLESO(FLESOConfig(), SMMParameters())
    for k in range(4):
        estimate = fleso_step(rig, k, POSITIONS[k], None)
        applied = np.zeros(2) if k == 0 else np.array(commands(k - 1))  # 0 before the first command
        np.testing.assert_array_equal(estimate, direct.step(np.array(POSITIONS[k]), applied, DT))
        if k < 3:
            publish_command(rig, node, k)
    assert node.command_fallback_late == 0
    # Late (real time): the command of stamp 3 has not arrived; the newest one (stamp 2) is used, counted.
    rig.publish(topics.TORQUE_COMMAND, command_msg(2 * MS, commands(2)))  # re-publication: harmless
    rig.settle(0.05)
    estimate = fleso_step(rig, 4, POSITIONS[4], None)
    np.testing.assert_array_equal(estimate, direct.step(np.array(POSITIONS[4]), np.array(commands(2)), DT))
    assert node.command_fallback_late == 1
    rows = msg_to_labelled(rig.wait_for(INTERNALS_TOPIC_OF_FLESO, 5)[4])
    np.testing.assert_array_equal(rows.row(COMMAND_FALLBACK_LATE_ROW), [1.0, 1.0])
    # The command of stamp 3 arriving after all does not change what stamp 5 uses: the command of 4.
    publish_command(rig, node, 3)
    publish_command(rig, node, 4)
    estimate = fleso_step(rig, 5, POSITIONS[5], None)
    np.testing.assert_array_equal(estimate, direct.step(np.array(POSITIONS[5]), np.array(commands(4)), DT))
    assert node.command_fallback_late == 1


def test_fleso_effort_wins_over_the_commands(make_rig: Any, ros_context: Any) -> None:
    node = FlesoNode(context=ros_context)
    rig = make_rig(node)
    rig.record(topics.DISTURBANCE_ESTIMATE)
    direct = FLESO(FLESOConfig(), SMMParameters())
    for k in range(3):
        effort = (1.0 - 0.2 * k, -0.7 + 0.1 * k)
        estimate = fleso_step(rig, k, POSITIONS[k], effort)
        np.testing.assert_array_equal(estimate, direct.step(np.array(POSITIONS[k]), np.array(effort), DT))
        publish_command(rig, node, k)
    assert node.command_fallback_late == 0


def test_fleso_drops_a_bad_torque_command(make_rig: Any, ros_context: Any) -> None:
    node = FlesoNode(context=ros_context)
    rig = make_rig(node)
    rig.record(topics.DISTURBANCE_ESTIMATE)
    rig.publish(topics.TORQUE_COMMAND, command_msg(0, (1.0, 2.0)))
    assert rig.spin_until(lambda: node.newest_command_stamp_ns == 0)
    bad = list(bad_arrays(lambda stamp: command_msg(stamp, (5.0, 5.0)), MS).values())
    for msg in bad:
        rig.publish(topics.TORQUE_COMMAND, msg)
    assert rig.spin_until(lambda: node.counters.dropped_invalid == len(bad))
    assert node.newest_command_stamp_ns == 0
    direct = FLESO(FLESOConfig(), SMMParameters())
    # Stamp 0: first step (torque 0); 1: the command of 0; 2: the command of 1 was bad, so the newest held
    # (that of 0) is used and counted as late.
    for k, applied in enumerate([(0.0, 0.0), (1.0, 2.0), (1.0, 2.0)]):
        estimate = fleso_step(rig, k, POSITIONS[k], None)
        np.testing.assert_array_equal(estimate, direct.step(np.array(POSITIONS[k]), np.array(applied), DT))
    assert node.command_fallback_late == 1


# ---------------------------------------------------------------------------------------- controller


@pytest.mark.parametrize("velocity_source", ["observer", "td"])
def test_the_law_takes_the_velocity_of_its_velocity_source(
    make_rig: Any, ros_context: Any, velocity_source: str
) -> None:
    node = ControllerNode(
        context=ros_context, parameter_overrides={"fpdeso.velocity_source": velocity_source}
    )
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    td_velocity, observer_velocity = (0.3, 0.4), (-0.7, 0.9)
    rig.publish(topics.JOINT_STATES_FILTERED, filtered(0, velocity=td_velocity))
    rig.publish(topics.REFERENCE, reference_msg(0))
    rig.publish(topics.DISTURBANCE_ESTIMATE, estimate_msg(0, velocity=observer_velocity))
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    law = FPDESOController(FPDESOConfig(velocity_source=velocity_source), SMMParameters())
    velocity = observer_velocity if velocity_source == "observer" else td_velocity
    expected = law.step(
        SineReference().evaluate(0.0), np.array((0.1, -0.2)), np.array(velocity), np.array((0.2, -0.1)), DT
    )
    np.testing.assert_array_equal(msg_to_torque(torques[0]).values, expected)


def feed_controller(
    rig: Any, stamp_ns: int, with_estimate: bool, xi: tuple[float, float] = (0.2, -0.1)
) -> None:
    rig.publish(topics.JOINT_STATES_FILTERED, filtered(stamp_ns))
    rig.publish(topics.REFERENCE, reference_msg(stamp_ns))
    if with_estimate:
        rig.publish(topics.DISTURBANCE_ESTIMATE, estimate_msg(stamp_ns, xi))


def direct_torque(controller: Any, stamp_ns: int, xi: tuple[float, float] = (0.2, -0.1)) -> np.ndarray:
    sample = filtered(stamp_ns)
    return controller.step(
        SineReference().evaluate(stamp_ns / 1e9),
        np.array(sample.position),
        np.array(sample.velocity),
        np.array(xi),
        DT,
    )


def test_fpdeso_waits_for_all_three_inputs_and_answers_with_the_law_output(
    make_rig: Any, ros_context: Any
) -> None:
    node = ControllerNode(context=ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    internals = rig.record(topics.CONTROLLER_INTERNALS)
    direct = FPDESOController(FPDESOConfig(), SMMParameters())
    rig.publish(topics.JOINT_STATES_FILTERED, filtered(0))
    rig.publish(topics.REFERENCE, reference_msg(0))
    rig.settle(0.1)
    assert torques == []
    rig.publish(topics.DISTURBANCE_ESTIMATE, estimate_msg(0))
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    command = msg_to_torque(torques[0])
    assert command.stamp_ns == 0
    np.testing.assert_array_equal(command.values, direct_torque(direct, 0))
    rig.wait_for(topics.CONTROLLER_INTERNALS, 1)
    rows = msg_to_labelled(internals[0])
    # The law's rows carry the chain's labels, as with chain: internal and offline.
    np.testing.assert_array_equal(rows.row("controller.tau"), command.values)
    law_rows = {f"controller.{key}" for key in direct.internals}
    assert law_rows | {"dropped_invalid"} <= set(rows.row_labels)


@pytest.mark.parametrize(("algorithm", "law"), [("pid", PIDController), ("npd", NPDController)])
def test_baselines_need_no_disturbance_estimate(
    make_rig: Any, ros_context: Any, algorithm: str, law: Any
) -> None:
    node = ControllerNode(context=ros_context, parameter_overrides={"algorithm": algorithm})
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    direct = law()
    for k in range(3):
        feed_controller(rig, k * MS, with_estimate=False)
        rig.wait_for(topics.TORQUE_COMMAND, k + 1)
        np.testing.assert_array_equal(msg_to_torque(torques[k]).values, direct_torque(direct, k * MS))


def test_controller_bad_input_on_every_subscription_produces_no_torque(
    make_rig: Any, ros_context: Any
) -> None:
    node = ControllerNode(context=ros_context)
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    bad = [(topics.JOINT_STATES_FILTERED, m) for m in bad_filtered(MS).values()]
    bad += [(topics.REFERENCE, m) for m in bad_arrays(reference_msg, MS).values()]
    bad += [(topics.DISTURBANCE_ESTIMATE, m) for m in bad_arrays(estimate_msg, MS).values()]
    wrong_rows = labelled_to_msg([[0.1, 0.2]], ("something_else",), MS)
    bad.append((topics.DISTURBANCE_ESTIMATE, wrong_rows))
    not_a_reference = estimate_msg(MS)  # a valid labelled array, but not a 3x2 reference
    bad.append((topics.REFERENCE, not_a_reference))
    for topic, msg in bad:
        rig.publish(topic, msg)
    rig.settle(0.1)
    assert torques == []
    feed_controller(rig, 2 * MS, with_estimate=True)
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    rig.settle()
    assert [msg_to_torque(m).stamp_ns for m in torques] == [2 * MS]
    assert node.counters.dropped_invalid == len(bad)
    assert node.last_answered_stamp_ns == 2 * MS


def test_controller_duplicate_and_stale_inputs(make_rig: Any, ros_context: Any) -> None:
    node = ControllerNode(context=ros_context, parameter_overrides={"algorithm": "pid"})
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    direct = PIDController()
    for k in (1, 2):
        feed_controller(rig, k * MS, with_estimate=False)
        rig.wait_for(topics.TORQUE_COMMAND, k)
        direct_torque(direct, k * MS)
    rig.publish(topics.REFERENCE, reference_msg(2 * MS))  # re-transmission: re-published, PID not stepped
    rig.wait_for(topics.TORQUE_COMMAND, 3)
    assert list(torques[2].data) == list(torques[1].data)
    rig.publish(topics.JOINT_STATES_FILTERED, filtered(MS))  # stale: dropped
    feed_controller(rig, 3 * MS, with_estimate=False)
    rig.wait_for(topics.TORQUE_COMMAND, 4)
    rig.settle()
    assert len(torques) == 4
    np.testing.assert_array_equal(msg_to_torque(torques[3]).values, direct_torque(direct, 3 * MS))
    assert node.counters.duplicates_answered == 1
    assert node.counters.dropped_stale == 1


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("fpdeso.fuzzy.kp0", [-4050.0, 4150.0], "kp0 must be > 0 for both joints"),
        ("fpdeso.fuzzy.k_e", [2.0, 6.0, 1.0], "fpdeso.fuzzy.k_e must have 2 values (alpha, beta), got 3"),
        ("fpdeso.robust_gain", [0.1], "fpdeso.robust_gain must have 2 values (alpha, beta), got 1"),
        ("pid.kd", [-1.5, 0.5], "kd must be >= 0 for both joints"),
        ("npd.rho_p", [0.0, 0.6], "rho_p must be > 0 for both joints"),
        ("fpd.fuzzy.k1", [100.0, 5.0], "k1 must be < kp0"),
        ("model.I11", -0.1, "model.I11 out of range Min: 0.0"),
        ("algorithm", "lqr", "algorithm must be one of"),
        ("switch_idle_time", -1.0, "switch_idle_time out of range Min: 0.0"),
    ],
)
def test_invalid_gains_are_rejected_with_the_reason_and_change_nothing(
    make_rig: Any, ros_context: Any, name: str, value: Any, reason: str
) -> None:
    node = ControllerNode(context=ros_context)
    make_rig(node)
    controller_before = node.controller
    value_before = node.get_parameter(name).value
    (result,) = node.set_parameters([Parameter(name, value=value)])
    assert not result.successful
    assert reason in result.reason
    assert node.controller is controller_before
    assert node.get_parameter(name).value == value_before


def test_a_valid_gain_change_acts_on_the_next_step(make_rig: Any, ros_context: Any) -> None:
    node = ControllerNode(context=ros_context)
    rig = make_rig(node)
    law = node.controller
    torques = rig.record(topics.TORQUE_COMMAND)
    feed_controller(rig, 0, with_estimate=True)
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    results = node.set_parameters(
        [
            Parameter("fpdeso.fuzzy.kp0", value=[2000.0, 2500.0]),
            Parameter("fpdeso.robust_gain", value=[0.0, 0.0]),
        ]
    )
    assert all(r.successful for r in results)
    assert node.controller is law  # reconfigured in place
    feed_controller(rig, MS, with_estimate=True)
    rig.wait_for(topics.TORQUE_COMMAND, 2)
    new_config = FPDESOConfig(fuzzy=FuzzyPDConfig(kp0=(2000.0, 2500.0)), robust_gain=(0.0, 0.0))
    old_law = FPDESOController(FPDESOConfig(), SMMParameters())
    new_law = FPDESOController(new_config, SMMParameters())
    np.testing.assert_array_equal(msg_to_torque(torques[1]).values, direct_torque(new_law, MS))
    assert not np.allclose(direct_torque(old_law, MS), direct_torque(new_law, MS))


def test_a_runtime_gain_change_is_logged_with_its_old_and_new_value(
    make_rig: Any, ros_context: Any, capfd: pytest.CaptureFixture[str]
) -> None:
    node = ControllerNode(context=ros_context)
    make_rig(node)
    capfd.readouterr()
    (result,) = node.set_parameters([Parameter("fpdeso.fuzzy.k_e", value=[3.0, 6.0])])
    assert result.successful
    logged = [line for line in "".join(capfd.readouterr()).splitlines() if "fpdeso.fuzzy.k_e" in line]
    assert len(logged) == 1 and logged[0].endswith(
        "[controller_node]: parameter fpdeso.fuzzy.k_e: [2.0, 6.0] -> [3.0, 6.0]"
    ), logged


def test_pid_gain_change_keeps_the_integrator_and_acts_on_the_next_step(
    make_rig: Any, ros_context: Any
) -> None:
    node = ControllerNode(context=ros_context, parameter_overrides={"algorithm": "pid"})
    rig = make_rig(node)
    law = node.controller
    torques = rig.record(topics.TORQUE_COMMAND)
    direct = PIDController()
    for k in range(3):
        feed_controller(rig, k * MS, with_estimate=False)
        rig.wait_for(topics.TORQUE_COMMAND, k + 1)
        direct_torque(direct, k * MS)
    (result,) = node.set_parameters([Parameter("pid.ki", value=[100.0, 200.0])])
    assert result.successful
    assert node.controller is law
    feed_controller(rig, 3 * MS, with_estimate=False)
    rig.wait_for(topics.TORQUE_COMMAND, 4)
    new_config = PIDConfig(ki=(100.0, 200.0))
    direct.reconfigure(new_config)
    np.testing.assert_array_equal(msg_to_torque(torques[3]).values, direct_torque(direct, 3 * MS))
    # What a rebuild did: the integrator and derivative filter restarted at 0, a torque step.
    restarted = PIDController(new_config)
    assert not np.allclose(msg_to_torque(torques[3]).values, direct_torque(restarted, 3 * MS))


def test_a_model_change_reconfigures_a_running_fpdeso(make_rig: Any, ros_context: Any) -> None:
    node = ControllerNode(context=ros_context)
    rig = make_rig(node)
    law = node.controller
    torques = rig.record(topics.TORQUE_COMMAND)
    feed_controller(rig, 0, with_estimate=True)
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    (result,) = node.set_parameters([Parameter("model.I44", value=0.1)])
    assert result.successful
    assert node.controller is law
    feed_controller(rig, MS, with_estimate=True)
    rig.wait_for(topics.TORQUE_COMMAND, 2)
    heavier = FPDESOController(FPDESOConfig(), SMMParameters(I44=0.1))
    np.testing.assert_array_equal(msg_to_torque(torques[1]).values, direct_torque(heavier, MS))
    nominal = FPDESOController(FPDESOConfig(), SMMParameters())
    assert not np.allclose(direct_torque(heavier, MS), direct_torque(nominal, MS))


def test_gains_of_a_law_that_is_not_running_are_used_when_it_is_switched_in(
    make_rig: Any, ros_context: Any
) -> None:
    node = ControllerNode(context=ros_context, parameter_overrides={"switch_idle_time": 0.0})
    rig = make_rig(node)
    law = node.controller
    torques = rig.record(topics.TORQUE_COMMAND)
    (result,) = node.set_parameters([Parameter("npd.k_np", value=[40.0, 10.0])])
    assert result.successful
    assert node.controller is law and node.algorithm == "fpdeso"
    (result,) = node.set_parameters([Parameter("algorithm", value="npd")])
    assert result.successful
    feed_controller(rig, 0, with_estimate=False)
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    retuned = NPDController(NPDConfig(k_np=(40.0, 10.0)))
    np.testing.assert_array_equal(msg_to_torque(torques[0]).values, direct_torque(retuned, 0))


def test_algorithm_switch_is_refused_while_the_loop_runs_and_accepted_when_idle(
    make_rig: Any, ros_context: Any
) -> None:
    node = ControllerNode(context=ros_context, parameter_overrides={"switch_idle_time": 0.2})
    rig = make_rig(node)
    torques = rig.record(topics.TORQUE_COMMAND)
    (accepted,) = node.set_parameters([Parameter("algorithm", value="npd")])  # nothing received yet: idle
    assert accepted.successful and node.algorithm == "npd"
    feed_controller(rig, 0, with_estimate=False)
    rig.wait_for(topics.TORQUE_COMMAND, 1)
    (refused,) = node.set_parameters([Parameter("algorithm", value="fpdeso")])
    assert not refused.successful
    assert re.search(r"cannot change from 'npd' to 'fpdeso' while the loop is active", refused.reason)
    assert node.algorithm == "npd" and node.get_parameter("algorithm").value == "npd"
    time.sleep(0.25)
    (accepted,) = node.set_parameters([Parameter("algorithm", value="fpdeso")])
    assert accepted.successful and node.algorithm == "fpdeso"
    # The new law runs from the next stamp, and now waits for the disturbance estimate too.
    feed_controller(rig, MS, with_estimate=False)
    rig.settle(0.1)
    assert len(torques) == 1
    rig.publish(topics.DISTURBANCE_ESTIMATE, estimate_msg(MS))
    rig.wait_for(topics.TORQUE_COMMAND, 2)
    fresh = FPDESOController(FPDESOConfig(), SMMParameters())
    np.testing.assert_array_equal(msg_to_torque(torques[1]).values, direct_torque(fresh, MS))
