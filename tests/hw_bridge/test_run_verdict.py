"""RunTally: control periods and the late ones after the settling time, from feedback frames; the verdict."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_hw_bridge.protocol import NO_COMMAND_AGE, FeedbackFrame, StatusBit
from smm_hw_bridge.run_verdict import HostVerdictConfig, RunTally, VerdictConfig

PERIOD_NS = 1_000_000


def frame(tick: int, *, enabled: bool = True, age: int = 1, session: int = 5) -> FeedbackFrame:
    """A feedback frame of ``tick``; the command on the valves answers tick ``tick - age``."""
    return FeedbackFrame(
        session=session,
        seq=tick + 1,
        tick=tick,
        host_session=9,
        counts=(0, 0),
        adc=(0, 0, 0, 0),
        status=int(StatusBit.ENABLED) if enabled else 0,
        faults=0,
        applied_seq=0,
        applied_age=age if enabled else NO_COMMAND_AGE,
        output_codes=(0, 0),
        late_commands=0,
        crc_errors=0,
        dropped_frames=0,
    )


def tally_of(
    frames: list[FeedbackFrame], *, armed: bool = True, limit: float = 0.01, divider: int = 1
) -> RunTally:
    tally = RunTally(PERIOD_NS, VerdictConfig(late_limit=limit, settle_s=0.1), divider)
    tally.armed = armed
    for item in frames:
        tally.on_feedback(item)
    return tally


def board_frames(divider: int, delays: list[int]) -> list[FeedbackFrame]:
    """The frames a board sends when the command answering control tick ``k * divider`` is latched
    ``delays[k]`` ticks after it (the newest latched command stays on the valves, as the board keeps it)."""
    latched = sorted((k * divider + delay, k * divider) for k, delay in enumerate(delays))
    frames, newest = [], None
    for tick in range(len(delays) * divider):
        while latched and latched[0][0] <= tick:
            _, answered = latched.pop(0)
            newest = answered if newest is None else max(newest, answered)
        frames.append(frame(tick, enabled=newest is not None, age=0 if newest is None else tick - newest))
    return frames


def test_a_run_that_never_armed_did_not_control() -> None:
    tally = tally_of([frame(t, enabled=False) for t in range(500)], armed=False)
    assert tally.verdict() == "the bridge never armed: no enabled command reached the board"


def test_an_armed_run_whose_output_never_went_live_did_not_control() -> None:
    tally = tally_of([frame(t, enabled=False) for t in range(500)])
    assert tally.verdict() is not None and "never went live" in tally.verdict()  # type: ignore[operator]


def test_late_ticks_in_the_settling_time_are_not_judged_and_those_after_are() -> None:
    # Ticks 10..109 settle (100 ticks of 1 ms); every one of them late: not judged.
    frames = [frame(t, enabled=False) for t in range(10)]
    frames += [frame(t, age=2) for t in range(10, 110)]
    frames += [frame(t) for t in range(110, 1110)]
    tally = tally_of(frames)
    assert (tally.live_ticks, tally.periods, tally.late_periods) == (1100, 1000, 0)
    assert tally.verdict() is None
    assert tally.figures() == (
        "late 0 of 1000 periods of 1 ms after the first 0.1 s live (0.00 %), 1100 live ticks in all"
    )


@pytest.mark.parametrize(("late", "controlled"), [(10, True), (11, False)])
def test_more_late_ticks_than_the_limit_after_the_settling_time_did_not_control(
    late: int, controlled: bool
) -> None:
    frames = [frame(t) for t in range(100)]
    frames += [frame(t, age=2 if t < 100 + late else 1) for t in range(100, 1100)]
    tally = tally_of(frames)
    assert (tally.periods, tally.late_periods) == (1000, late)
    assert (tally.verdict() is None) is controlled
    if not controlled:
        assert tally.verdict() == (
            "1.10 % of the control periods after the first 0.1 s live were late or not live, above the "
            "limit of 1 %"
        )


def test_a_lost_frame_counts_its_ticks_and_their_late_ones_with_the_next_frame() -> None:
    # the command on the valves at 205 answers 201: the periods ending at 203, 204 and 205 were late
    frames = [frame(t) for t in range(200)] + [frame(205, age=4)]
    tally = tally_of(frames, limit=1.0)
    assert (tally.periods, tally.late_periods) == (100 + 6, 3)


def test_a_re_sent_frame_and_a_new_session_are_not_counted_twice() -> None:
    frames = [frame(t) for t in range(200)] + [frame(199), frame(200, session=6)]
    tally = tally_of(frames)
    assert tally.periods == 100


@given(st.floats(min_value=-10, max_value=-1e-9) | st.floats(min_value=1.0 + 1e-9, max_value=10))
def test_a_late_limit_outside_0_1_is_rejected_with_its_name(limit: float) -> None:
    with pytest.raises(ValueError, match="late_limit"):
        VerdictConfig(late_limit=limit)


def test_a_bad_period_is_rejected() -> None:
    with pytest.raises(ValueError, match="period_ns"):
        RunTally(0)


def test_ticks_without_live_output_after_the_settling_time_count_as_late() -> None:
    # live for 0.2 s, then nulled by the board's watchdog for the rest: not a controlled run
    frames = [frame(t) for t in range(200)] + [frame(t, enabled=False) for t in range(200, 1200)]
    tally = tally_of(frames)
    assert (tally.live_ticks, tally.periods, tally.late_periods) == (200, 1100, 1000)
    assert tally.verdict() is not None and "were late or not live" in tally.verdict()  # type: ignore[operator]
    back = tally_of([*frames, frame(1205)], limit=1.0)  # live again after lost frames
    assert (back.periods, back.late_periods) == (1106, 1005)  # 5 of the 6 periods since were not live


def test_ticks_without_a_frame_are_counted_and_shown() -> None:
    tally = tally_of([frame(t) for t in range(150)] + [frame(160, age=12)])
    assert (tally.missed_ticks, tally.periods, tally.late_periods) == (
        10,
        61,
        11,
    )  # at most the ticks passed
    assert tally.figures().endswith(", 10 ticks without a frame here")


def test_a_board_holding_its_command_between_control_ticks_is_not_late() -> None:
    # 250 Hz on a 1 kHz board: the board holds each command 3 ticks of 4, which its own late count (per
    # tick) would call late; per control period the run is on time
    tally = tally_of(board_frames(4, [1] * 500), divider=4)
    assert (tally.periods, tally.late_periods, tally.verdict()) == (474, 0, None)
    assert tally.figures().startswith("late 0 of 474 periods of 4 ms after the first 0.1 s live")


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from([1, 2, 4, 10]).flatmap(
        lambda divider: st.tuples(
            st.just(divider),
            st.lists(st.integers(1, 2 * divider), min_size=130 // divider, max_size=200 // divider + 20),
        )
    )
)
def test_a_period_is_late_exactly_when_its_command_reached_the_valves_after_the_next_control_tick(
    case: tuple[int, list[int]],
) -> None:
    divider, delays = case
    tally = tally_of(board_frames(divider, delays), limit=1.0, divider=divider)
    # period k ends at control tick (k + 1) N; judged once 100 ticks (0.1 s) after the first live tick
    judged = [k for k in range(len(delays) - 1) if (k + 1) * divider - delays[0] >= 100]
    assert tally.periods == len(judged) > 0
    assert tally.late_periods == sum(delays[k] > divider for k in judged)


@pytest.mark.parametrize("divider", [0, -1, True, 1.5])
def test_a_bad_divider_is_rejected(divider: object) -> None:
    with pytest.raises(ValueError, match="divider"):
        RunTally(PERIOD_NS, divider=divider)  # type: ignore[arg-type]


def test_a_link_with_one_feedback_a_period_misses_no_tick_between_and_a_skipped_slot_is_late() -> None:
    tally = RunTally(PERIOD_NS, VerdictConfig(late_limit=0.01, settle_s=0.1), divider=5, every=5)
    tally.armed = True
    for tick in range(0, 2000, 5):  # CANopen at 200 Hz: each SYNC's feedback answers the last one
        tally.on_feedback(frame(tick, age=5))
    assert tally.missed_ticks == 0 and tally.late_periods == 0
    tally.on_feedback(frame(2005, age=10))  # slot 2000 skipped: the valves held its setpoint a period
    assert tally.missed_ticks == 5 and tally.late_periods == 1


@pytest.mark.parametrize("every", [1, 5])
def test_a_run_is_past_its_plan_once_its_live_span_covers_it(every: int) -> None:
    """A fault after the planned live length (an emulated bench fell silent at its end) leaves the verdict."""
    tally = RunTally(PERIOD_NS, VerdictConfig(settle_s=0.1), every, every)
    for tick in range(0, 300 * every, every):
        tally.on_feedback(frame(tick, enabled=tick >= 100 * every, age=0))
    assert tally.live_s() == pytest.approx(200 * every * PERIOD_NS / 1e9)  # ticks 100N .. 299N, N each
    planned = 200 * every * PERIOD_NS / 1e9
    assert not tally.before_plan(planned)
    assert not tally.before_plan(planned + every * PERIOD_NS / 1e9)  # one control period short: still done
    assert tally.before_plan(planned + 2 * every * PERIOD_NS / 1e9)
    assert tally.before_plan(0.0) and RunTally(PERIOD_NS).before_plan(0.0)  # no plan: every fault counts
    assert RunTally(PERIOD_NS).live_s() == 0.0 and RunTally(PERIOD_NS).before_plan(0.01)


def test_the_host_verdict_config_checks_its_plan() -> None:
    assert HostVerdictConfig(planned_s=20.0).planned_s == 20.0
    with pytest.raises(ValueError, match="planned_s"):
        HostVerdictConfig(planned_s=-1.0)


def test_ending_the_run_needs_a_planned_length() -> None:
    assert HostVerdictConfig(planned_s=2.0, ends_run=True).ends_run
    with pytest.raises(ValueError, match="ends_run needs planned_s > 0"):
        HostVerdictConfig(ends_run=True)
