"""RunTally: enabled and late ticks after the settling time, from feedback frames, and the run's verdict."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_hw_bridge.protocol import FeedbackFrame, StatusBit
from smm_hw_bridge.run_verdict import RunTally, VerdictConfig

PERIOD_NS = 1_000_000


def frame(tick: int, *, enabled: bool = True, late: int = 0, session: int = 5) -> FeedbackFrame:
    """A feedback frame of ``tick`` with the board's cumulative late count ``late``."""
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
        applied_age=0,
        output_codes=(0, 0),
        late_commands=late,
        crc_errors=0,
        dropped_frames=0,
    )


def tally_of(frames: list[FeedbackFrame], *, armed: bool = True, limit: float = 0.01) -> RunTally:
    tally = RunTally(PERIOD_NS, VerdictConfig(late_limit=limit, settle_s=0.1))
    tally.armed = armed
    for item in frames:
        tally.on_feedback(item)
    return tally


def test_a_run_that_never_armed_did_not_control() -> None:
    tally = tally_of([frame(t, enabled=False) for t in range(500)], armed=False)
    assert tally.verdict() == "the bridge never armed: no enabled command reached the board"


def test_an_armed_run_whose_output_never_went_live_did_not_control() -> None:
    tally = tally_of([frame(t, enabled=False) for t in range(500)])
    assert tally.verdict() is not None and "never went live" in tally.verdict()  # type: ignore[operator]


def test_late_ticks_in_the_settling_time_are_not_judged_and_those_after_are() -> None:
    # Ticks 10..109 settle (100 ticks of 1 ms); every one of them late: not judged.
    frames = [frame(t, enabled=False) for t in range(10)]
    frames += [frame(t, late=t - 9) for t in range(10, 110)]
    frames += [frame(t, late=100) for t in range(110, 1110)]
    tally = tally_of(frames)
    assert (tally.live_ticks, tally.enabled_ticks, tally.late_ticks) == (1100, 1000, 0)
    assert tally.verdict() is None
    assert (
        tally.figures() == "late 0 of 1000 ticks after the first 0.1 s live (0.00 %), 1100 live ticks in all"
    )


@pytest.mark.parametrize(("late", "controlled"), [(10, True), (11, False)])
def test_more_late_ticks_than_the_limit_after_the_settling_time_did_not_control(
    late: int, controlled: bool
) -> None:
    frames = [frame(t) for t in range(100)]
    frames += [frame(t, late=min(t - 99, late)) for t in range(100, 1100)]
    tally = tally_of(frames)
    assert (tally.enabled_ticks, tally.late_ticks) == (1000, late)
    assert (tally.verdict() is None) is controlled
    if not controlled:
        assert tally.verdict() == (
            "1.10 % of the ticks after the first 0.1 s live were late or not live, above the limit of 1 %"
        )


def test_a_lost_frame_counts_its_ticks_and_their_late_ones_with_the_next_frame() -> None:
    frames = [frame(t) for t in range(200)] + [frame(205, late=3)]
    tally = tally_of(frames, limit=1.0)
    assert (tally.enabled_ticks, tally.late_ticks) == (100 + 6, 3)


def test_a_re_sent_frame_and_a_new_session_are_not_counted_twice() -> None:
    frames = [frame(t) for t in range(200)] + [frame(199), frame(200, session=6, late=0)]
    tally = tally_of(frames)
    assert tally.enabled_ticks == 100


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
    assert (tally.live_ticks, tally.enabled_ticks, tally.late_ticks) == (200, 1100, 1000)
    assert tally.verdict() is not None and "were late or not live" in tally.verdict()  # type: ignore[operator]
    back = tally_of([*frames, frame(1205, late=0)], limit=1.0)  # live again after lost frames
    assert (back.enabled_ticks, back.late_ticks) == (1106, 1005)  # 5 of the 6 ticks since were not live


def test_ticks_without_a_frame_are_counted_and_shown() -> None:
    tally = tally_of([frame(t) for t in range(150)] + [frame(160, late=12)])
    assert (tally.missed_ticks, tally.enabled_ticks, tally.late_ticks) == (
        10,
        61,
        11,
    )  # at most the ticks passed
    assert tally.figures().endswith(", 10 ticks without a frame here")
