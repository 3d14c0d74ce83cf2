"""smm_sim.core: both clock modes' stepping, stamp matching, timeout, statistics, health, record; no ROS."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_node_runtime.health import Level
from smm_node_runtime.run_verdict import VerdictConfig
from smm_sim.core import (
    DEADLINE_MISS_WARN_FRACTION,
    PUBLISHED_STAMPS_KEPT,
    CommandOutcome,
    LatencyStats,
    PlantDivergedError,
    SimCore,
    statistics_summary,
)
from smm_sim.plant import SimulatedPlant

from smm_sim.config import PlantParameters, SimNodeConfig

PERIOD = 1_000_000  # ns, the default control period
T0 = 5_000_000_000  # ns, an arbitrary monotonic start


def lockstep(**changes: object) -> SimCore:
    config = SimNodeConfig(clock_mode="lockstep", republish_period=0.02, **changes)  # type: ignore[arg-type]
    core = SimCore(PlantParameters(), config, T0)
    core.sent(T0)
    return core


def realtime(plant: PlantParameters | None = None, **changes: object) -> SimCore:
    config = SimNodeConfig(clock_mode="realtime", **changes)  # type: ignore[arg-type]
    core = SimCore(plant or PlantParameters(), config, T0)
    core.sent(T0)
    return core


def run_realtime(core: SimCore, ticks: int, *, answer: tuple[float, float] | None, start_ns: int) -> int:
    """Tick ``ticks`` times one period apart from ``start_ns``; answer each measurement at once (if given)."""
    now = start_ns
    for _ in range(ticks):
        if answer is not None:
            assert core.on_command(core.stamp_ns, answer, now + 1000) is CommandOutcome.ACCEPTED
        now += PERIOD
        core.tick(now)
        core.sent(now)
    return now


# ---- lockstep ---------------------------------------------------------------------------------------


def test_lockstep_steps_once_per_answer_to_the_current_measurement() -> None:
    core = lockstep()
    assert core.on_command(0, (0.5, -0.5), T0) is CommandOutcome.STEPPED
    assert core.steps == 1 and core.stamp_ns == PERIOD
    np.testing.assert_array_equal(core.plant.internals["commanded_torque"], [0.5, -0.5])
    assert core.on_command(0, (9.0, 9.0), T0) is CommandOutcome.LATE  # a re-sent answer to stamp 0
    assert (core.steps, core.ignored_late) == (1, 1)
    np.testing.assert_array_equal(core.plant.internals["commanded_torque"], [0.5, -0.5])


@given(st.integers(min_value=-(10**12), max_value=10**12).filter(lambda stamp: stamp != 0))
def test_lockstep_never_steps_on_a_stamp_other_than_the_current_one(stamp_ns: int) -> None:
    core = lockstep()
    outcome = core.on_command(stamp_ns, (1.0, 1.0), T0)
    assert core.steps == 0
    if stamp_ns < 0:
        assert outcome is CommandOutcome.LATE and core.ignored_late == 1
    else:
        assert outcome is CommandOutcome.UNKNOWN_STAMP and core.dropped_unknown_stamp == 1


def test_lockstep_republishes_an_unanswered_measurement_once_a_period_has_passed() -> None:
    core = lockstep()  # republish_period 20 ms, sent at T0
    assert not core.republish_due(T0 + 10 * PERIOD)
    assert core.republish_due(T0 + 20 * PERIOD) and core.republished == 1
    core.sent(T0 + 20 * PERIOD)
    assert not core.republish_due(T0 + 30 * PERIOD)
    core.reconfigure(SimNodeConfig(clock_mode="lockstep", republish_period=0.005))
    assert core.republish_due(T0 + 30 * PERIOD) and core.republished == 2


def test_lockstep_run_ends_at_the_step_limit_and_not_before() -> None:
    core = lockstep(max_steps=3)
    for step in range(3):
        assert not core.finished
        core.on_command(step * PERIOD, (0.0, 0.0), T0 + step)
    assert core.finished and core.failure is None and core.steps == 3
    assert not core.republish_due(T0 + 10**12), "a finished run publishes nothing more"


def test_lowering_the_step_limit_below_the_steps_done_ends_the_run() -> None:
    core = lockstep()
    for step in range(5):
        core.on_command(step * PERIOD, (0.0, 0.0), T0)
    core.reconfigure(SimNodeConfig(clock_mode="lockstep", duration=0.004))
    assert core.finished and core.step_limit == 4
    with pytest.raises(ValueError, match="clock_mode"):
        core.reconfigure(SimNodeConfig(clock_mode="realtime"))


def test_the_same_seed_and_commands_give_the_same_run() -> None:
    def record(seed: int) -> dict[str, list[object]]:
        plant = PlantParameters(seed=seed, noise_std=(0.01, 0.01))
        core = SimCore(plant, SimNodeConfig(clock_mode="lockstep", record_file="x.npz"), T0)
        for _ in range(30):
            command = 1.0 - 5.0 * core.measurement.position
            core.on_command(core.stamp_ns, (float(command[0]), float(command[1])), T0)
        assert core.recorder is not None
        return dict(vars(core.recorder))

    first, second, other = record(3), record(3), record(4)
    assert first == second
    assert first["measured_position"] != other["measured_position"]


def test_the_record_matches_the_offline_plant_step_for_step(tmp_path: Path) -> None:
    path = tmp_path / "run" / "record.npz"
    stats = tmp_path / "stats.json"
    core = lockstep(max_steps=20, record_file=str(path), stats_file=str(stats))
    plant = SimulatedPlant(PlantParameters().plant_config)
    commands = [(0.1 * step, -0.05 * step) for step in range(20)]
    for command in commands:
        core.on_command(core.stamp_ns, command, T0 + core.steps * 1000)
        plant.step(command, 1e-3)
    core.write_outputs()
    data = np.load(path)
    np.testing.assert_array_equal(data["stamp_ns"], np.arange(21) * PERIOD)
    np.testing.assert_array_equal(data["command_stamp_ns"], np.arange(20) * PERIOD)
    np.testing.assert_array_equal(data["command"], commands)
    np.testing.assert_array_equal(data["position"][-1], plant.ground_truth.position)
    assert data["position"].shape == (21, 2) and data["velocity"].shape == (21, 2)
    written = json.loads(stats.read_text())
    assert written["steps"] == 20 and written["clock_mode"] == "lockstep"
    assert written["stepping_wall_s"] == pytest.approx(19_000 / 1e9)


def test_no_record_is_kept_unless_asked_for_at_start(tmp_path: Path) -> None:
    core = lockstep()
    core.reconfigure(SimNodeConfig(clock_mode="lockstep", record_file=str(tmp_path / "late.npz")))
    core.on_command(0, (0.0, 0.0), T0)
    core.write_outputs()
    assert core.recorder is None and not (tmp_path / "late.npz").exists()


def test_a_diverging_plant_ends_the_run_as_failed() -> None:
    core = lockstep()
    core.on_command(0, (1e300, -1e300), T0)  # finite, so accepted, but no integrator survives it
    assert core.finished and isinstance(core.failure, PlantDivergedError)
    assert "non-finite" in str(core.failure)
    health = core.health({}, {}, 0.0)
    assert health.level is Level.ERROR and "diverged" in health.message


def test_steps_ending_on_a_stop_are_counted() -> None:
    core = SimCore(PlantParameters(initial_position=(1.3, 0.0)), SimNodeConfig(clock_mode="lockstep"), T0)
    core.on_command(0, (50.0, 0.0), T0)  # pushes alpha into its stop
    assert core.ticks_on_stop == 1
    assert core.health({}, core.health_counts(), 0.0).level is Level.WARN


# ---- real time ----------------------------------------------------------------------------------------


def test_realtime_applies_the_latest_answer_at_the_next_tick_and_measures_its_latency() -> None:
    core = realtime()
    assert core.on_command(0, (0.7, -0.3), T0 + 250_000) is CommandOutcome.ACCEPTED
    assert core.steps == 0, "real time steps on the timer, not on the command"
    assert core.tick(T0 + PERIOD) is None
    np.testing.assert_array_equal(core.plant.internals["commanded_torque"], [0.7, -0.3])
    assert core.latency.count == 1 and core.latency.percentile_us(50.0) == 250.0
    assert core.deadline_misses == 0 and core.stale_ticks == 0


def test_realtime_gives_zero_torque_without_a_command_and_after_the_timeout() -> None:
    core = realtime(command_timeout=0.02, record_file="unused.npz")
    core.tick(T0 + PERIOD)
    assert (core.stale_ticks, core.command_timeouts) == (1, 0), "no command yet: waiting, not a timeout"
    core.sent(T0 + PERIOD)
    core.on_command(PERIOD, (0.7, -0.3), T0 + PERIOD)
    now = T0 + PERIOD
    ages = []
    for _ in range(40):
        now += PERIOD
        ages.append(core.tick(now))
        core.sent(now)
    timed_out = [age for age in ages if age is not None]
    assert len(timed_out) == 40 - 20 and timed_out[0] == 21 * PERIOD
    assert core.command_timeouts == 20 and "zero torque" in core.last_error
    assert core.recorder is not None
    commands = np.asarray(core.recorder.command)
    np.testing.assert_array_equal(commands[1:21], np.tile([0.7, -0.3], (20, 1)))
    np.testing.assert_array_equal(commands[21:], np.zeros((20, 2)))
    assert core.recorder.command_stamp_ns[21:] == [-1] * 20
    health = core.health({}, core.health_counts(), 0.0)
    assert health.level is Level.ERROR and "zero torque" in health.message


def test_realtime_matches_answers_to_published_stamps() -> None:
    core = realtime()
    end = run_realtime(core, 3, answer=None, start_ns=T0)
    assert core.on_command(2 * PERIOD, (1.0, 0.0), end) is CommandOutcome.ACCEPTED
    assert core.on_command(PERIOD, (2.0, 0.0), end) is CommandOutcome.LATE  # older than the one in force
    assert core.on_command(2 * PERIOD, (2.0, 0.0), end) is CommandOutcome.LATE  # repeated
    assert core.on_command(9 * PERIOD, (2.0, 0.0), end) is CommandOutcome.UNKNOWN_STAMP  # never published
    assert core.on_command(2 * PERIOD + 1, (2.0, 0.0), end) is CommandOutcome.UNKNOWN_STAMP
    assert (core.ignored_late, core.dropped_unknown_stamp, core.latency.count) == (2, 2, 1)


def test_realtime_forgets_publish_times_beyond_the_newest_thousand() -> None:
    core = realtime(command_timeout=0.5)
    end = run_realtime(core, PUBLISHED_STAMPS_KEPT + 5, answer=None, start_ns=T0)
    assert core.on_command(0, (1.0, 0.0), end) is CommandOutcome.LATE  # too old to match: ignored quietly
    assert core.on_command(core.stamp_ns, (1.0, 0.0), end) is CommandOutcome.ACCEPTED


def test_deadline_misses_and_late_ticks_are_counted_per_tick() -> None:
    answered = realtime()
    run_realtime(answered, 10, answer=(0.0, 0.0), start_ns=T0)
    assert answered.deadline_misses == 0 and answered.late_ticks == 0
    unanswered = realtime()
    run_realtime(unanswered, 10, answer=None, start_ns=T0)
    assert unanswered.deadline_misses == 9  # every tick after the first found the previous one unanswered
    late = realtime()
    late.tick(T0 + 3 * PERIOD)  # two periods late
    late.tick(T0 + 4 * PERIOD)  # on time again: the schedule restarts from the late tick
    assert late.late_ticks == 1


def test_realtime_run_ends_after_its_duration() -> None:
    core = realtime(duration=0.005)
    run_realtime(core, 5, answer=(0.0, 0.0), start_ns=T0)
    assert core.finished and core.steps == 5


# ---- the real-time verdict (docs/LAUNCH.md, "Shutdown and exit codes") ---------------------------------

SETTLE = VerdictConfig(late_limit=0.01, settle_s=0.01)  # 10 ticks of 1 ms settle


def judged(answers: list[bool], *, verdict: VerdictConfig = SETTLE, command_timeout: float = 0.05) -> SimCore:
    """A real-time run of one tick per entry; ``True``: the measurement before that tick was answered."""
    config = SimNodeConfig(clock_mode="realtime", command_timeout=command_timeout)
    core = SimCore(PlantParameters(), config, T0, verdict)
    now = T0
    core.sent(now)
    for answered in answers:
        if answered:
            assert core.on_command(core.stamp_ns, (0.0, 0.0), now + 1000) is CommandOutcome.ACCEPTED
        now += PERIOD
        core.tick(now)
        core.sent(now)
    return core


def test_a_realtime_run_without_any_command_did_not_control() -> None:
    core = judged([False] * 20)
    assert core.run_verdict() == "no torque command reached the plant: all 20 ticks applied zero torque"
    assert core.statistics()["verdict"] == core.run_verdict()


def test_the_verdict_judges_the_ticks_after_the_settling_time_from_the_first_command() -> None:
    # 5 ticks before the first command (zero torque, not judged), 10 settling ticks, then 100 judged.
    core = judged([False] * 5 + [True] * 110)
    assert (core.first_live_tick, core.judged_ticks, core.late_judged) == (5, 100, 0)
    assert core.run_verdict() is None
    assert core.verdict_figures() == (
        "late 0 of 100 periods of 1 ms after the first 0.01 s live (0.00 %), "
        "5 zero-torque ticks before the first command (not judged)"
    )


@pytest.mark.parametrize(("late", "controlled"), [(1, True), (2, False)])
def test_deadline_misses_above_the_late_limit_mean_the_run_did_not_control(
    late: int, controlled: bool
) -> None:
    # A measurement left unanswered makes the next tick miss its deadline; the command in force holds.
    answers = [True] * 110
    for index in range(late):
        answers[50 + 10 * index] = False
    core = judged(answers)
    assert (core.judged_ticks, core.late_judged, core.zero_torque_judged) == (100, late, 0)
    if controlled:
        assert core.run_verdict() is None
    else:
        assert core.run_verdict() == (
            "2.00 % of the control periods after the first 0.01 s live were late or not live, above the "
            "limit of 1 %"
        )


def test_the_users_run_of_a_fifth_of_the_deadlines_missed_did_not_control() -> None:
    # 7,883 of 40,000 steps missed their deadline (19.7 %): one in five here, the same verdict.
    core = judged([True] * 10 + [index % 5 != 0 for index in range(1000)])
    assert core.deadline_misses == 200 and core.zero_torque_judged == 0
    reason = core.run_verdict()
    assert reason is not None and reason.startswith("20.00 % of the control periods")


def test_a_zero_torque_tick_after_the_settling_time_means_the_run_did_not_control() -> None:
    # Four unanswered measurements with a 2 ms timeout: the held command times out for three ticks (more
    # than 2 ms old at each); below a late limit of 100 % the zero torque alone is the reason.
    answers = [True] * 110
    answers[60:64] = [False] * 4
    core = judged(answers, verdict=VerdictConfig(late_limit=1.0, settle_s=0.01), command_timeout=0.002)
    assert core.command_timeouts == 3 and core.zero_torque_judged == 3
    assert core.run_verdict() == (
        "3 ticks after the first 0.01 s live applied zero torque (no valid command within command_timeout "
        "2 ms)"
    )


def test_zero_torque_while_settling_is_not_judged() -> None:
    answers = [True] * 110
    answers[2:6] = [False] * 4  # times out for three ticks within the first 10 after the first command
    core = judged(answers, command_timeout=0.002)
    assert core.command_timeouts == 3 and core.zero_torque_judged == 0 and core.late_judged == 0
    assert core.run_verdict() is None


def test_a_lockstep_run_is_not_judged() -> None:
    core = lockstep()
    assert core.run_verdict() is None and core.statistics()["verdict"] is None


# ---- health and statistics ------------------------------------------------------------------------


def test_health_thresholds() -> None:
    core = lockstep()
    assert core.health({}, {}, 0.0).message == "waiting for the first command"
    core.on_command(0, (0.0, 0.0), T0)
    fine = core.health({"steps": 1000}, {}, 1000.0)
    assert fine.level is Level.OK and fine.message == "stepping" and fine.values["loop_rate_hz"] == "1000.0"
    for name in ("dropped_invalid", "dropped_unknown_stamp", "ticks_on_stop", "late_ticks"):
        health = core.health({name: 1}, {}, 0.0)
        assert health.level is Level.WARN and name in health.message
        assert core.health({}, {name: 1}, 0.0).level is Level.WARN, "the current period counts too"
    limit = int(DEADLINE_MISS_WARN_FRACTION * 1000)
    assert core.health({"steps": 1000, "deadline_misses": limit}, {}, 0.0).level is Level.OK
    assert core.health({"steps": 1000, "deadline_misses": limit + 1}, {}, 0.0).level is Level.WARN
    assert core.health({"command_timeouts": 1, "late_ticks": 1}, {}, 0.0).level is Level.ERROR


def test_invalid_commands_are_counted_and_never_step() -> None:
    core = lockstep()
    assert core.reject_command() == 1 and core.reject_command() == 2
    assert core.steps == 0 and core.statistics()["dropped_invalid"] == 2


def test_publications_are_counted_per_topic() -> None:
    core = lockstep()
    for topic in ("/smm/joint_states", "/clock", "/smm/joint_states"):
        core.count_published(topic)
    assert core.statistics()["published"] == {"/clock": 1, "/smm/joint_states": 2}


def test_statistics_summary_says_what_each_clock_mode_measures() -> None:
    steps = lockstep()
    for step in range(3):
        steps.on_command(step * PERIOD, (0.0, 0.0), T0 + step * 1_000_000)
    summary = statistics_summary(steps.statistics())
    assert summary.startswith("3 steps at 1000 steps/s (lockstep)") and "latency" not in summary
    quiet = realtime()
    run_realtime(quiet, 7, answer=None, start_ns=T0)
    quiet.reject_command()
    summary = statistics_summary(quiet.statistics())
    assert "no command answered a measurement" in summary and "nan" not in summary
    assert "deadline misses 6" in summary and "dropped 1 invalid, 0 unknown-stamp commands" in summary
    answered = realtime()
    run_realtime(answered, 4, answer=(0.0, 0.0), start_ns=T0)
    summary = statistics_summary(answered.statistics())
    assert "latency p50 1 us, p99 1 us (4 answers)" in summary and "zero-torque ticks 0;" in summary


def test_latency_percentiles_match_numpy() -> None:
    rng = np.random.default_rng(1)
    samples = rng.integers(10_000, 2_000_000, size=999)
    stats = LatencyStats()
    for value in samples:
        stats.add(int(value))
    summary = stats.summary()
    assert summary["count"] == 999
    assert summary["p50_us"] == pytest.approx(np.percentile(samples, 50) / 1e3)
    assert summary["p99_us"] == pytest.approx(np.percentile(samples, 99) / 1e3)
    assert summary["max_us"] == pytest.approx(samples.max() / 1e3)
    assert math.isnan(LatencyStats().summary()["p50_us"])
