"""The direct loop's host against the emulator (in-process thread, loopback UDP).

A chain that raises or gives a non-finite torque: safe frame and the error transition. Parameters change
between ticks only, validated as in the topics loop. Every topic of the topics loop is published with the
measurement's stamp. Periodicity and execution time on /diagnostics.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from hw_bridge.test_bridge_node import Bench, assert_safe_now
from smm_hw_bridge.protocol import Reason

pytestmark = pytest.mark.ros


@pytest.fixture
def direct(ros_context: Any) -> Iterator[Bench]:
    harness = Bench(
        ros_context, loop="direct", **{"bridge.validity_ticks": 5000}
    )  # safe frames, not the board
    try:
        yield harness
    finally:
        harness.close()


def _break_chain(bench: Bench, step: Any) -> None:
    chain = bench.controller.chain
    assert chain is not None
    chain.step_floats = step


def _assert_faulted(bench: Bench, words: str) -> None:
    assert_safe_now(bench)
    assert bench.spin_until(lambda: bench.node.lifecycle_state == "unconfigured", 5.0)
    assert bench.spin_until(
        lambda: any(s.level == b"\x02" and words in s.message for s in bench.bridge_statuses()), 5.0
    ), [s.message for s in bench.bridge_statuses()]


def test_a_chain_that_raises_sends_a_safe_frame_and_goes_through_the_error_transition(direct: Bench) -> None:
    direct.start()

    def raises(*_args: Any) -> tuple[float, float]:
        raise ZeroDivisionError("a broken law")

    _break_chain(direct, raises)
    _assert_faulted(direct, "control chain failed")


def test_a_non_finite_torque_sends_a_safe_frame_and_goes_through_the_error_transition(direct: Bench) -> None:
    direct.start()
    _break_chain(direct, lambda *_args: (math.nan, 0.0))
    _assert_faulted(direct, "control chain failed")
    assert direct.controller.counters.invalid_outputs >= 1


def test_parameters_change_between_ticks_only_and_are_validated(direct: Bench) -> None:
    from rclpy.parameter import Parameter

    direct.start()
    core = direct.controller.core
    before = core.gains["pid"].kp
    results: list[Any] = []
    with direct.node.loop.lock:  # as a tick holds it
        setter = threading.Thread(
            target=lambda: results.extend(
                direct.controller.set_parameters([Parameter("pid.kp", value=[50.0, 50.0])])
            )
        )
        setter.start()
        setter.join(5.0)
        assert results and results[0].successful  # taken and handed over ...
        time.sleep(0.3)
        assert core.gains["pid"].kp == before != (50.0, 50.0)  # ... but not applied within a tick
    assert direct.spin_until(lambda: core.gains["pid"].kp == (50.0, 50.0), 5.0)  # at the next tick's start
    assert direct.controller.law_parameters["pid"].config.kp == (50.0, 50.0)
    refused = direct.controller.set_parameters([Parameter("pid.kp", value=[-1.0, 50.0])])[0]
    assert not refused.successful and "kp" in refused.reason
    assert direct.spin_until(direct.live)  # the loop runs on


def test_a_stamp_policy_change_waits_for_the_next_tick(direct: Bench) -> None:
    from rclpy.parameter import Parameter

    direct.start()
    gate = direct.controller.admission.gate
    before = gate.policy.max_ahead_periods
    results: list[Any] = []
    with direct.node.loop.lock:  # as a tick holds it
        setter = threading.Thread(
            target=lambda: results.extend(
                direct.controller.set_parameters([Parameter("stamp.max_ahead_periods", value=before + 7)])
            )
        )
        setter.start()
        setter.join(5.0)
        assert results and results[0].successful  # taken and handed over ...
        time.sleep(0.3)
        assert gate.policy.max_ahead_periods == before  # ... but not applied within a tick
    assert direct.spin_until(lambda: gate.policy.max_ahead_periods == before + 7, 5.0)  # at the next tick
    assert direct.spin_until(direct.live)  # the loop runs on


def test_the_topics_loop_topics_are_published_with_the_measurement_stamps(direct: Bench) -> None:
    from sensor_msgs.msg import JointState
    from smm_msgs_py.conversions import msg_to_labelled, msg_to_reference, msg_to_torque, stamp_to_ns
    from std_msgs.msg import Float64MultiArray

    from smm_msgs_py import topics

    received: dict[str, list[int]] = {name: [] for name in ("joint_states", "torque_command", "reference")}
    internals: list[Any] = []
    direct.peer.create_subscription(
        JointState,
        topics.JOINT_STATES,
        lambda m: received["joint_states"].append(stamp_to_ns(m.header.stamp)),
        1000,
    )
    for name, parse in (("torque_command", msg_to_torque), ("reference", msg_to_reference)):
        direct.peer.create_subscription(
            Float64MultiArray, name, lambda m, n=name, p=parse: received[n].append(p(m).stamp_ns), 1000
        )
    direct.peer.create_subscription(Float64MultiArray, topics.CONTROLLER_INTERNALS, internals.append, 1000)
    direct.start()
    assert direct.spin_until(lambda: len(received["torque_command"]) > 50 and len(internals) > 50, 10.0)
    measured = set(received["joint_states"])
    assert set(received["torque_command"]) <= measured
    assert set(received["reference"]) <= set(received["torque_command"])
    assert direct.internals, "no hw_bridge_internals"
    rows = msg_to_labelled(internals[-1]).row_labels
    from smm_node_runtime import COUNTER_ROWS

    # the internal chain's rows, then the node counters, as controller_node publishes them in the topics loop
    assert rows[0].startswith("td.") and any(label.startswith("controller.") for label in rows)
    assert rows[-len(COUNTER_ROWS) :] == COUNTER_ROWS


def test_the_rehearsal_publishes_every_topic_of_the_run_an_hour_ahead_and_the_run_starts_afresh(
    direct: Bench,
) -> None:
    """The preflight's rehearsal (output disabled) publishes what the run does, stamped ahead; then the run's
    own stamps are answered from the first, without a time jump (the hosted gate forgets the rehearsal)."""
    from rclpy.lifecycle import TransitionCallbackReturn
    from sensor_msgs.msg import JointState
    from smm_hw_bridge.loop import REHEARSAL_STAMP_OFFSET_NS
    from smm_hw_bridge.preflight import RehearsalRecorder
    from smm_msgs_py.conversions import msg_to_labelled, msg_to_reference, msg_to_torque, stamp_to_ns
    from std_msgs.msg import Float64MultiArray

    from smm_msgs_py import topics

    stamps: dict[str, list[int]] = {name: [] for name in ("joint_states", "torque_command", "reference")}
    stamps["controller_internals"], stamps["hw_bridge_internals"] = [], []
    peer = direct.peer
    peer.create_subscription(
        JointState,
        topics.JOINT_STATES,
        lambda m: stamps["joint_states"].append(stamp_to_ns(m.header.stamp)),
        1000,
    )
    for name, parse in (
        ("torque_command", msg_to_torque),
        ("reference", msg_to_reference),
        ("controller_internals", msg_to_labelled),
        ("hw_bridge_internals", msg_to_labelled),
    ):
        peer.create_subscription(
            Float64MultiArray, name, lambda m, n=name, p=parse: stamps[n].append(p(m).stamp_ns), 1000
        )
    node = direct.node
    assert node.trigger_configure() == TransitionCallbackReturn.SUCCESS
    assert node.core is not None
    with node.loop.lock:
        node.loop.rehearsal = RehearsalRecorder(node.core.config.period_ns)
    assert direct.spin_until(lambda: all(len(s) > 30 for s in stamps.values()), 10.0), stamps
    with node.loop.lock:  # between two ticks
        assert node.loop.end_rehearsal() is not None
        rehearsed = {name: list(values) for name, values in stamps.items()}
        for values in stamps.values():
            values.clear()
    assert all(not direct.live() for _ in range(3))  # nothing of it reached the valves
    assert all(stamp >= REHEARSAL_STAMP_OFFSET_NS for values in rehearsed.values() for stamp in values)
    assert node.trigger_activate() == TransitionCallbackReturn.SUCCESS
    assert direct.spin_until(direct.live), "the output never went live"
    ahead = REHEARSAL_STAMP_OFFSET_NS
    run_stamps = lambda: all(sum(s < ahead for s in v) > 30 for v in stamps.values())  # noqa: E731
    assert direct.spin_until(run_stamps, 10.0), stamps
    # The rehearsal's last messages may still be in flight when it ends; one writer per topic delivers in
    # order, so none of them follows the run's first message.
    for name, values in stamps.items():
        first = next(index for index, stamp in enumerate(values) if stamp < ahead)
        assert all(stamp < ahead for stamp in values[first:]), name
    counters = direct.controller.counters
    assert counters.time_jumps == 0 and counters.dropped_stale == 0 and counters.dropped_ahead == 0


def test_periodicity_and_execution_time_are_on_diagnostics(direct: Bench) -> None:
    direct.start()
    assert direct.spin_until(lambda: direct.node.loop.statistics.execution_us.count > 100, 10.0)
    assert direct.spin_until(lambda: len(direct.bridge_statuses()) >= 2, 5.0)
    values = {kv.key: kv.value for kv in direct.bridge_statuses()[-1].values}
    for figure in ("periodicity", "execution_time"):
        for label in ("mean_us", "min_us", "max_us", "std_us"):
            assert float(values[f"{figure}.{label}"]) >= 0.0
    assert float(values["execution_time.p99_us"]) >= float(values["execution_time.p50_us"]) > 0.0
    assert "host: late" in direct.node.closing_line()


def test_a_chain_that_stops_answering_is_caught_by_the_host_watchdog(direct: Bench) -> None:
    """Refused measurements (no command) are not a fault: the board holds, then the host watchdog nulls."""
    direct.start()
    trips = direct.node.core.watchdog_trips
    from smm_controller.core import Refusal

    direct.controller.core.measurement = lambda _topic, stamp_ns, *_measurement: Refusal(
        stamp_ns, "dropped_stale", "", ""
    )
    assert_safe_now(direct)
    assert direct.node.core.watchdog_trips > trips
    assert direct.node.lifecycle_state == "active"  # no error transition: the loop runs on, with safe output


def test_each_answered_measurement_gets_one_command_and_torque_command_is_only_an_output(
    direct: Bench,
) -> None:
    """The hosted chain's own torque_command, or another publisher's, is never taken as a second command."""
    from smm_msgs_py.conversions import torque_to_msg
    from std_msgs.msg import Float64MultiArray

    from smm_msgs_py import topics

    outside = direct.peer.create_publisher(Float64MultiArray, topics.TORQUE_COMMAND, 10)
    direct.start()
    core = direct.node.core

    def push_outside() -> bool:
        outside.publish(torque_to_msg(np.zeros(2), core.stamp_ns))
        return direct.node.loop.statistics.execution_us.count > 300

    assert direct.spin_until(push_outside, 10.0)
    with direct.node.loop.lock:  # between two ticks
        answered = direct.node.loop.statistics.execution_us.count
        assert direct.node.counters.commands == answered
    assert direct.node.counters.bad_commands == 0 and not direct.node.counters.refused


class _Recorded:
    """A device that notes each read's timeout and gives a reading on the calls listed."""

    def __init__(self, frames_on: set[int]) -> None:
        self.timeouts: list[float] = []
        self.frames_on = frames_on

    def read(self, timeout_s: float = 0.0) -> Any:
        self.timeouts.append(timeout_s)
        return Reason.CRC if len(self.timeouts) in self.frames_on else None


@pytest.mark.parametrize("spin_us", [0, 150])
def test_the_reader_sleeps_until_spin_us_before_the_next_frame_is_due_then_polls(spin_us: int) -> None:
    """spin_us = 0: one blocking wait per frame; else a wait ending spin_us before the frame is due, polls."""
    from smm_hw_bridge.bridge_health import BridgeCounters
    from smm_hw_bridge.core import BridgeConfig, BridgeCore
    from smm_hw_bridge.loop import BridgeLoop
    from smm_hw_bridge.reading import LINK_CHECK_S, LoopSettings

    loop = BridgeLoop(BridgeCounters(), settings=LoopSettings(spin_us=spin_us))
    device = _Recorded(frames_on={1, 2} if spin_us == 0 else {1, 5})
    loop.core, loop.device = BridgeCore(BridgeConfig(), host_session=1), device  # type: ignore[assignment]
    assert loop.read() is Reason.CRC  # no frame yet: the plain wait, a link check's period
    assert device.timeouts == [LINK_CHECK_S]
    assert loop.read() is Reason.CRC
    if spin_us == 0:
        assert device.timeouts == [LINK_CHECK_S, LINK_CHECK_S]
    else:
        sleep, *polls = device.timeouts[1:]
        assert 0.0 < sleep <= (1_000_000 - spin_us * 1000) / 1e9  # wakes spin_us before it is due
        assert polls == [0.0, 0.0, 0.0]  # then polls, no sleep, until it comes


def test_spin_us_is_validated() -> None:
    from smm_hw_bridge.reading import LoopSettings

    assert LoopSettings().spin_us > 0  # the direct loop polls by default (docs/LAUNCH.md)
    for bad in (-1, 100_001, 1.5, True):
        with pytest.raises(ValueError, match="spin_us"):
            LoopSettings(spin_us=bad)  # type: ignore[arg-type]


def test_the_work_done_ahead_after_each_send_changes_no_answer(direct: Bench) -> None:
    """Each answer is bit for bit that of a core stepped on the same measurements without prepare().

    The direct loop calls ControllerCore.prepare after each send (the FLESO's model terms and the next
    reference, done ahead); the plain core has the hosted one's settings and forgets the rehearsal too.
    """
    from rclpy.parameter import Parameter
    from smm_controller.core import ControllerCore, CoreSettings
    from smm_node_runtime.admission import InputAdmission

    from smm_msgs_py import topics

    controller = direct.controller
    controller.set_parameters([Parameter("algorithm", value="fpdeso")])  # the law with the FLESO
    calls: list[tuple[Any, ...]] = []
    step, forget = controller.core.measurement, direct.hosted.forget

    def recorded_step(topic: str, stamp_ns: int, position: Any, effort: Any, clock_ns: int) -> Any:
        calls.append((stamp_ns, position, effort, step(topic, stamp_ns, position, effort, clock_ns)))
        return calls[-1][-1]

    def recorded_forget() -> None:
        calls.append(())
        forget()

    controller.core.measurement, direct.hosted.forget = recorded_step, recorded_forget
    direct.start()
    assert direct.spin_until(lambda: len(calls) > 400, 10.0)
    with direct.node.loop.lock:  # between two ticks
        answers = list(calls)
    hosted = controller.core
    assert hosted.chain is not None and hosted.chain.fleso is not None and hosted.plausibility is not None
    settings = CoreSettings(
        algorithm=hosted.algorithm,
        gains=hosted.gains,
        model=hosted.model,
        output_limits=hosted.limiter.config,
        control_period=hosted.control_period,
        chain=True,
        td=hosted.td,
        fleso=hosted.fleso,
        measurement_limits=hosted.plausibility.limits,
    )
    reference = controller.reference
    plain = ControllerCore(
        settings,
        InputAdmission(hosted.admission.gate.policy, hosted.control_period),
        reference=lambda: reference.generator,
    )
    for call in answers:
        if not call:
            plain.reset()  # the rehearsal is forgotten
            continue
        stamp_ns, position, effort, answer = call
        assert plain.measurement(topics.JOINT_STATES, stamp_ns, position, effort, 0) == answer


@pytest.mark.parametrize(
    "overrides",
    [
        {"chain": "external", "reference_source": "internal"},
        {"chain": "internal", "reference_source": "topic"},
    ],
)
def test_the_direct_loop_refuses_a_chain_it_cannot_step_whole(
    ros_context: Any, overrides: dict[str, str]
) -> None:
    from smm_direct_loop.host import compose

    with pytest.raises(ValueError, match="chain and reference_source must be 'internal'"):
        compose(ros_context, overrides, {})
