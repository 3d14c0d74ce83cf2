"""ControllerCore: what controller_node does per measurement, without ROS (times passed in)."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_controller.chain import make_chain
from smm_controller.core import Command, ControllerCore, CoreSettings, Refusal, default_gains
from smm_controller.fleso import FLESOConfig
from smm_controller.laws import law_names
from smm_controller.limits import MeasurementLimits, OutputLimitConfig
from smm_controller.reference import SineReference
from smm_controller.td import TrackingDifferentiatorConfig
from smm_node_runtime.admission import InputAdmission
from smm_node_runtime.stamp_gate import StampPolicy

from smm_dynamics import SMMParameters

PERIOD_NS = 1_000_000
TOPIC = "joint_states"


def make_core(algorithm: str = "fpdeso", **overrides: Any) -> ControllerCore:
    settings = CoreSettings(
        algorithm=algorithm,
        gains=default_gains(),
        model=SMMParameters(),
        output_limits=OutputLimitConfig(),
        control_period=1e-3,
        chain=True,
        td=TrackingDifferentiatorConfig(),
        fleso=FLESOConfig(),
        measurement_limits=MeasurementLimits(),
    )
    reference = overrides.pop("reference", SineReference())
    sampled = overrides.pop("sampled", lambda: reference)
    return ControllerCore(settings, InputAdmission(StampPolicy(), 1e-3), reference=sampled)


def position(k: int) -> tuple[float, float]:
    return (0.01 * math.sin(0.01 * k), 0.005 * math.cos(0.01 * k))


def run(core: ControllerCore, steps: int, first: int = 1) -> list[Command | Refusal]:
    stamps = range(first, first + steps)
    return [core.measurement(TOPIC, k * PERIOD_NS, position(k), (0.1, -0.1), 0) for k in stamps]


@pytest.mark.parametrize("name", law_names())
def test_each_measurement_gets_the_torque_of_the_chain_on_the_same_inputs(name: str) -> None:
    core = make_core(name)
    chain = make_chain(name, SMMParameters())
    reference = SineReference()
    results = run(core, 50)
    for k, result in enumerate(results, start=1):
        assert isinstance(result, Command) and result.stamp_ns == k * PERIOD_NS
        rows = reference.rows((k - 1) * PERIOD_NS / 1e9)  # t = 0 at the first answered stamp
        expected = chain.step_floats(position(k), (0.1, -0.1), rows, 1e-3)
        assert result.torque == expected
    assert core.admission.answered == 50


def test_a_stale_stamp_is_refused_and_counted() -> None:
    core = make_core()
    run(core, 5)
    refused = core.measurement(TOPIC, 2 * PERIOD_NS, position(2), (0.0, 0.0), 0)
    assert isinstance(refused, Refusal) and refused.counter == "dropped_stale" and not refused.chain_failed
    assert core.admission.counters.dropped_stale == 1 and "older than the last answered" in refused.message


def test_a_re_sent_stamp_gets_the_last_torque_again_without_a_step() -> None:
    core = make_core()
    (first,) = run(core, 1)
    again = core.measurement(TOPIC, PERIOD_NS, position(1), (0.1, -0.1), 0)
    assert isinstance(first, Command) and isinstance(again, Command)
    assert again.duplicate and again.torque == first.torque
    assert core.admission.answered == 1 and core.admission.counters.duplicates_answered == 1
    conflicting = core.measurement(TOPIC, PERIOD_NS, (0.3, 0.3), (0.1, -0.1), 0)
    assert isinstance(conflicting, Refusal) and conflicting.counter == "conflicting_duplicates"


def test_an_implausible_measurement_is_refused_before_the_chain_steps() -> None:
    core = make_core()
    run(core, 3)
    jump = core.measurement(TOPIC, 4 * PERIOD_NS, (1.0, 0.0), (0.0, 0.0), 0)
    assert isinstance(jump, Refusal) and jump.counter == "dropped_implausible"
    assert core.admission.counters.dropped_implausible == 1 and core.admission.answered == 3


def test_a_non_finite_torque_is_a_chain_failure_counted_as_an_invalid_output() -> None:
    core = make_core("pid")
    assert core.chain is not None
    core.chain.step_floats = lambda *_args: (math.nan, 0.0)  # type: ignore[method-assign]
    (result,) = run(core, 1)
    assert isinstance(result, Refusal) and result.chain_failed
    assert core.admission.counters.invalid_outputs == 1 and "finite" in result.message


def ramp_estimates(stamps: list[int], velocity: tuple[float, float]) -> dict[str, tuple[float, float]]:
    """The TD's and FLESO's velocity (rad/s) after a ramp (rad/s) measured at ``stamps`` (periods)."""
    core = make_core()
    for k in stamps:
        t = k * 1e-3
        result = core.measurement(TOPIC, k * PERIOD_NS, (velocity[0] * t, velocity[1] * t), (0.0, 0.0), 0)
        assert isinstance(result, Command) and all(math.isfinite(v) for v in result.torque)
    internals = core.internals()
    return {key: (float(internals[key][0]), float(internals[key][1])) for key in ("td.x2", "fleso.x2_hat")}


def test_missed_control_periods_are_caught_up_so_a_ramp_measured_every_third_period_has_its_velocity() -> (
    None
):
    # a loop that falls behind answers every third stamp: the chain must advance 3 ms, not 1 ms, per step
    estimates = ramp_estimates(list(range(1, 3001, 3)), (0.2, -0.1))
    assert estimates["td.x2"] == pytest.approx((0.2, -0.1), abs=1e-9)
    assert estimates["fleso.x2_hat"] == pytest.approx((0.2, -0.1), rel=0.02)


@settings(max_examples=15, deadline=None)
@given(
    gaps=st.lists(st.integers(1, 8), min_size=150, max_size=150),
    velocity=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3)),  # stays within the joints' range
)
def test_any_sequence_of_missed_periods_gives_the_ramp_velocity_and_finite_torques(
    gaps: list[int], velocity: tuple[float, float]
) -> None:
    stamps = [1]
    for gap in gaps:
        stamps.append(stamps[-1] + gap)
    estimates = ramp_estimates(stamps, velocity)
    assert estimates["td.x2"] == pytest.approx(velocity, abs=1e-6)


@settings(max_examples=15, deadline=None)
@given(
    gaps=st.lists(st.one_of(st.integers(1, 8), st.integers(101, 2_000)), min_size=60, max_size=60),
    amplitude=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)),
)
def test_stamps_with_gaps_and_forward_time_jumps_never_give_a_non_finite_torque(
    gaps: list[int], amplitude: tuple[float, float]
) -> None:
    core = make_core()
    k = 0
    for gap in gaps:
        k += gap
        for _ in range(core.admission.gate.policy.resync_samples):  # enough samples to resync after a jump
            position = (amplitude[0] * math.sin(2.0 * k * 1e-3), amplitude[1] * math.cos(3.0 * k * 1e-3))
            result = core.measurement(TOPIC, k * PERIOD_NS, position, (0.0, 0.0), 0)
            if isinstance(result, Command):
                assert all(math.isfinite(tau) for tau in result.torque)
            else:
                assert result.counter == "dropped_ahead", result
            k += 1
    assert core.admission.counters.time_jumps == sum(gap > 100 for gap in gaps[1:])


def test_missed_periods_count_the_stamps_between_steps_up_to_the_gate_window() -> None:
    core = make_core()
    assert core.missed_periods(5 * PERIOD_NS) == 0  # no step yet
    run(core, 1)
    window = core.admission.gate.max_ahead_ns // PERIOD_NS
    assert [core.missed_periods((1 + gap) * PERIOD_NS) for gap in (1, 2, 4, window)] == [0, 1, 3, window - 1]
    assert core.missed_periods((2 + window) * PERIOD_NS) == 0  # a time jump: one period, as documented
    core.reset()
    assert core.missed_periods(3 * PERIOD_NS) == 0  # a new run
    run(core, 1, first=10)
    core.switch("pid")
    assert core.missed_periods(13 * PERIOD_NS) == 0  # a fresh chain


def test_a_chain_that_has_not_stepped_has_nothing_to_catch_up() -> None:
    chain = make_chain("fpdeso", SMMParameters())
    chain.advance_estimators((0.2, 0.1), (0.0, 0.0), 1e-3, 5)
    assert chain.td.next_position(1e-3) is None  # still uninitialised: the first step starts at its y


def test_a_backward_time_jump_starts_a_fresh_run() -> None:
    core = make_core()
    run(core, 40, first=1000)
    policy = core.admission.gate.policy
    after = run(core, policy.resync_samples + 2, first=1)
    assert core.admission.counters.time_jumps == 1
    resynced = after[policy.resync_samples - 1 :]
    assert isinstance(resynced[0], Command) and resynced[0].verdict.backward
    # from the resynchronising sample on, the core behaves as a fresh one fed from that sample
    twin = make_core()
    expected = run(twin, 3, first=policy.resync_samples)
    assert [r.torque for r in resynced if isinstance(r, Command)] == [
        r.torque for r in expected if isinstance(r, Command)
    ]


def test_a_switch_is_refused_while_inputs_arrive_and_builds_the_new_law_fresh() -> None:
    core = make_core("fpdeso")
    assert core.switch_refusal("pid", 0.5, quiet_s=0.1) is not None
    assert core.switch_refusal("pid", 0.5, quiet_s=0.6) is None
    assert core.switch_refusal("fpdeso", 0.5, quiet_s=0.0) is None
    core.switch("pid")
    assert core.algorithm == "pid" and core.chain is not None and core.chain.fleso is None
    assert core.chain.controller is core.law


def test_new_gains_reach_the_running_law_in_place() -> None:
    from smm_controller.baselines import PIDConfig

    core = make_core("pid")
    run(core, 20)
    law = core.law
    integral = law.internals["i"].copy()
    core.set_gains("pid", PIDConfig(kp=(50.0, 50.0)))
    assert core.law is law and law.config.kp == (50.0, 50.0)  # type: ignore[attr-defined]
    assert (law.internals["i"] == integral).all()  # the integral is kept (the I term, ki unchanged)


@settings(max_examples=40, deadline=None)
@given(
    gaps=st.lists(st.integers(1, 3), min_size=3, max_size=25),
    prepared=st.lists(st.booleans(), min_size=25, max_size=25),
    switch_reference_at=st.integers(0, 25),
    back_at=st.integers(0, 25),
)
def test_prepare_ahead_changes_no_answer(
    gaps: list[int], prepared: list[bool], switch_reference_at: int, back_at: int
) -> None:
    """Answers with prepare() after some equal those without, bit for bit.

    Across lost stamps, a new reference generator after prepare(), and stamps that go back (refused, then
    a run that starts again: a reset).
    """
    generators = [SineReference()]
    ahead, plain = (make_core(sampled=lambda: generators[0]) for _ in range(2))
    stamp = 1
    for k, gap in enumerate(gaps):
        if prepared[k]:
            ahead.prepare()
        if k == switch_reference_at:
            generators[0] = SineReference(amplitude=(0.5, 0.25))  # a parameter change: a new generator
        stamp = 1 if k == back_at else stamp + gap
        measurement = (TOPIC, stamp * PERIOD_NS, position(stamp), (0.1, -0.1), 0)
        assert ahead.measurement(*measurement) == plain.measurement(*measurement)
        assert ahead.last_reference == plain.last_reference


def test_a_reset_forgets_the_reference_sampled_ahead() -> None:
    """prepare() sampled stamp 11 at t = 10 ms; once the run starts again at stamp 5 it is t = 6 ms."""
    ahead, plain = make_core(), make_core()
    stamps = [*range(1, 11), *range(1, 12)]  # back to 1: four refused, a reset at 5 (t = 0 there)
    for k, stamp in enumerate(stamps):
        if k == 9:
            ahead.prepare()
        measurement = (TOPIC, stamp * PERIOD_NS, position(stamp), (0.1, -0.1), 0)
        assert ahead.measurement(*measurement) == plain.measurement(*measurement)
        assert ahead.last_reference == plain.last_reference
    assert plain.admission.counters.time_jumps == 1 and plain.reference_clock.first_stamp_ns == 5 * PERIOD_NS
