"""The preflight's verdict from rehearsal figures: hold, refuse, the fastest rate held (no ROS, no clock)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_hw_bridge.idle_states import NO_LIMIT_US, IdleStates
from smm_hw_bridge.preflight import (
    WARM_UP_S,
    PreflightConfig,
    RehearsalFigures,
    RehearsalRecorder,
    judge,
    tick_grid,
)

PERIOD = 1_000_000  # 1 kHz board


def figures(latencies_us: list[float], unanswered: int = 0, divider: int = 1) -> RehearsalFigures:
    return RehearsalFigures(PERIOD, divider, tuple(latencies_us), (10.0,) * len(latencies_us), unanswered)


def test_fast_host_holds_every_rate() -> None:
    verdict = judge(figures([200.0] * 1000), 0.01)
    assert verdict.holds
    assert verdict.late_share == 0.0
    assert verdict.fastest_held_hz == 1000.0
    assert [rate for rate, _ in verdict.predicted] == [1000.0, 500.0, 250.0, 200.0, 100.0]


def test_host_late_at_1khz_refuses_and_names_500_hz() -> None:
    # 5 % of the answers take 1.5 ms: late at 1 kHz (budget 1 ms), in time at 500 Hz (2 ms)
    verdict = judge(figures([300.0] * 950 + [1500.0] * 50), 0.01)
    assert not verdict.holds
    assert verdict.late_share == pytest.approx(0.05)
    assert verdict.fastest_held_hz == 500.0
    text = verdict.refusal(direct_loop=False, realtime=False)
    assert "does not hold 1000 Hz" in text and "500 Hz" in text
    assert "--loop direct" in text and "--rt-priority" in text
    assert "--loop direct" not in verdict.refusal(direct_loop=True, realtime=False)
    assert "--rt-priority" not in verdict.refusal(direct_loop=False, realtime=True)


def test_only_250_hz_holds() -> None:
    verdict = judge(figures([300.0] * 900 + [3000.0] * 100), 0.01)
    assert verdict.fastest_held_hz == 250.0
    assert dict(verdict.predicted)[500.0] == pytest.approx(0.1)


def test_nothing_holds_says_so() -> None:
    verdict = judge(figures([20000.0] * 100), 0.01)  # beyond 100 Hz's 10 ms
    assert verdict.fastest_held_hz is None
    assert "none of the candidate rates holds" in verdict.refusal(direct_loop=True, realtime=True)


def test_the_unseen_share_is_added_to_every_prediction() -> None:
    rehearsal = figures([100.0] * 993 + [1500.0] * 7)  # 0.7 % late at 1 kHz, none at 500 Hz
    assert judge(rehearsal, 0.01).holds
    verdict = judge(rehearsal, 0.01, unseen_late=0.0035)
    assert verdict.late_share == pytest.approx(0.007)
    assert verdict.prediction == pytest.approx(0.0105)
    assert dict(verdict.predicted) == pytest.approx(
        {1000.0: 0.0105, 500.0: 0.0035, 250.0: 0.0035, 200.0: 0.0035, 100.0: 0.0035}
    )
    assert not verdict.holds and verdict.fastest_held_hz == 500.0
    text = verdict.refusal(direct_loop=True, realtime=True)
    assert "0.70 % of the rehearsed control periods were late" in text
    assert "predicted 1.05 % late (with 0.35 points a short rehearsal does not see)" in text
    assert "predicted: 1.05 % at 1000 Hz / 0.35 % at 500 Hz" in verdict.lines()[-1]
    assert judge(figures([20000.0] * 10), 1.0, unseen_late=0.5).prediction == 1.0  # a share, capped
    for bad in (-0.001, 1.5, float("nan")):
        with pytest.raises(ValueError, match="unseen_late"):
            judge(rehearsal, 0.01, unseen_late=bad)
        with pytest.raises(ValueError, match="unseen_late"):
            PreflightConfig(unseen_late=bad)


def test_unanswered_periods_count_as_late() -> None:
    verdict = judge(figures([100.0] * 97, unanswered=3), 0.01)
    assert verdict.late_share == pytest.approx(0.03)
    assert not verdict.holds and verdict.fastest_held_hz is None


def test_limit_is_inclusive() -> None:
    assert judge(figures([100.0] * 99 + [1500.0]), 0.01).holds
    assert not judge(figures([100.0] * 99 + [1500.0]), 0.0099).holds


def test_no_rehearsed_period_does_not_hold() -> None:
    assert not judge(figures([]), 0.01).holds


def test_rehearsed_at_500_hz_judges_its_own_period() -> None:
    verdict = judge(figures([1500.0] * 100, divider=2), 0.01)
    assert verdict.figures.rate_hz == 500.0
    assert verdict.holds and verdict.fastest_held_hz == 500.0


@given(st.lists(st.floats(0.0, 10_000.0), min_size=1, max_size=200), st.floats(0.0, 1.0))
def test_fastest_held_is_within_the_limit_and_every_faster_one_is_not(
    latencies: list[float], limit: float
) -> None:
    verdict = judge(figures(latencies), limit)
    for rate, share in verdict.predicted:
        if verdict.fastest_held_hz is not None and rate > verdict.fastest_held_hz:
            assert share > limit
    if verdict.fastest_held_hz is not None:
        assert dict(verdict.predicted)[verdict.fastest_held_hz] <= limit
    assert verdict.holds == (verdict.late_share <= limit)


def test_bad_limits_and_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="late_limit"):
        judge(figures([1.0]), 1.5)
    with pytest.raises(ValueError, match="dividers"):
        judge(figures([1.0]), 0.01, (0, 1))
    with pytest.raises(ValueError, match="duration_s"):
        PreflightConfig(duration_s=-1.0)
    with pytest.raises(ValueError, match="duration_s"):
        PreflightConfig(duration_s=31.0)
    with pytest.raises(ValueError, match="force"):
        PreflightConfig(force=1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="divider"):
        RehearsalRecorder(PERIOD, divider=0)


def record(
    recorder: RehearsalRecorder, ticks: range, way_ns: int, answer_ns: int, skip: frozenset[int] = frozenset()
) -> None:
    for tick in ticks:
        rx = 5_000_000_000 + tick * PERIOD + way_ns + (tick % 7) * 10_000
        control = tick % recorder.divider == 0
        recorder.on_feedback(tick, rx, control)
        if control and tick not in skip:
            recorder.on_answer(tick, rx + answer_ns)


def test_recorder_times_answers_from_the_tick_grid() -> None:
    recorder = RehearsalRecorder(PERIOD)
    record(recorder, range(2000), way_ns=40_000, answer_ns=100_000)
    result = recorder.figures()
    warm = round(WARM_UP_S * 1e9 / PERIOD)
    assert result.periods == 2000 - warm and result.unanswered == 0
    # wake-up: arrival after the earliest arrival's grid (0..60 us jitter); answer 100 us after arrival
    assert min(result.wakeup_us) == pytest.approx(0.0) and max(result.wakeup_us) == pytest.approx(60.0)
    assert min(result.feedback_to_command_us) == pytest.approx(100.0)
    assert max(result.feedback_to_command_us) == pytest.approx(160.0)


def test_recorder_counts_unanswered_control_periods_and_its_divider() -> None:
    recorder = RehearsalRecorder(PERIOD, divider=4, added_latency_us=1000.0)
    record(recorder, range(1000, 3000), way_ns=0, answer_ns=50_000, skip=frozenset({2000, 2004}))
    result = recorder.figures()
    assert result.unanswered == 2
    assert result.periods == (3000 - 1252) // 4  # control ticks from 1252 (after the warm-up) on
    assert min(result.feedback_to_command_us) == pytest.approx(1050.0)  # the added latency counts


def test_recorder_counts_lost_frames_as_unanswered_periods() -> None:
    recorder = RehearsalRecorder(PERIOD, divider=2)
    record(recorder, range(0, 1000), way_ns=0, answer_ns=50_000)
    record(recorder, range(1010, 2000), way_ns=0, answer_ns=50_000)  # 10 ticks lost: 5 control periods
    result = recorder.figures()
    assert result.unanswered == 5
    assert result.periods == (2000 - 250) // 2


def test_recorder_without_frames_gives_nothing() -> None:
    result = RehearsalRecorder(PERIOD).figures()
    assert result.periods == 0 and not judge(result, 0.01).holds


def test_tick_grid_follows_a_drifting_board_clock() -> None:
    ticks = np.arange(3000, dtype=np.int64)
    drift = (ticks * 50) // 1000  # 50 ppm: the board's tick is 1.00005 ms on the host's clock
    jitter = (ticks % 5) * 20_000
    arrivals = 7_000 + ticks * PERIOD + drift + jitter
    grid = tick_grid(ticks, arrivals, PERIOD)
    after = arrivals - grid
    assert after.min() >= 0
    assert np.abs(after - jitter).max() <= 2  # the drift is taken out, the jitter remains


def test_the_rehearsal_reports_the_idle_state_setting_beside_the_wake_up() -> None:
    held = IdleStates(0, (("POLL", 0), ("C1", 2)))
    recorder = RehearsalRecorder(PERIOD, idle_states=held)
    record(recorder, range(2000), way_ns=40_000, answer_ns=100_000)
    lines = judge(recorder.figures(), 0.01).lines()
    wake = next(i for i, line in enumerate(lines) if line.startswith("wake-up"))
    assert lines[wake + 1] == f"idle states: {held.statement()}"


def test_a_refusal_names_the_idle_states_only_when_they_are_not_held() -> None:
    slow = [300.0] * 900 + [3000.0] * 100

    def refusal(idle: IdleStates | None) -> str:
        rehearsal = RehearsalFigures(PERIOD, 1, tuple(slow), (10.0,) * len(slow), 0, idle)
        return judge(rehearsal, 0.01).refusal(direct_loop=True, realtime=True)

    assert "/dev/cpu_dma_latency" in refusal(IdleStates(NO_LIMIT_US, (("POLL", 0), ("C6", 133))))
    assert "/dev/cpu_dma_latency" in refusal(IdleStates(None, (), "permission denied"))
    assert "/dev/cpu_dma_latency" not in refusal(IdleStates(0, (("POLL", 0), ("C6", 133))))
    assert "/dev/cpu_dma_latency" not in refusal(None)


def test_recorder_of_a_link_with_one_feedback_a_period_counts_only_its_missing_feedbacks() -> None:
    recorder = RehearsalRecorder(PERIOD, divider=5, every=5)  # CANopen at 200 Hz: a SYNC every 5 ticks
    record(recorder, range(0, 1000, 5), way_ns=0, answer_ns=50_000)
    record(recorder, range(1005, 2000, 5), way_ns=0, answer_ns=50_000)  # slot 1000 skipped: one period
    result = recorder.figures()
    assert result.unanswered == 1
    assert len(result.feedback_to_command_us) == (2000 - 250) // 5 - 1
