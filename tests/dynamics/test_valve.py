"""smm_dynamics.valve: the first-order valve lag against its closed form."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_dynamics.valve import valve_lag_goal, valve_lag_step, valve_time_constants_from_response_times

RISE, FALL, H = 0.02, 0.01, 1e-3


def closed_form(start: float, goal: float, time_constant: float) -> tuple[float, float]:
    """x(h) and the mean of x over [0, h] for x' = (goal - x) / T, x(0) = start."""
    end = goal + (start - goal) * math.exp(-H / time_constant)
    mean = goal + (start - goal) * time_constant / H * (1.0 - math.exp(-H / time_constant))
    return end, mean


@pytest.mark.parametrize(
    ("start", "goal", "time_constant"),
    [
        (0.0, 5.0, RISE),  # opening from null
        (0.0, -5.0, RISE),
        (2.0, 5.0, RISE),  # opening further
        (-2.0, -5.0, RISE),
        (5.0, 2.0, FALL),  # closing
        (-5.0, -2.0, FALL),
        (5.0, -5.0, FALL),  # reversing: closes through null
        (-5.0, 5.0, FALL),
        (1e-170, 2e-170, RISE),  # a product of the two would underflow to 0 and pick T_fall
        (-1e-170, -2e-170, RISE),
    ],
)
def test_valve_lag_step_opens_with_t_rise_and_closes_with_t_fall(
    start: float, goal: float, time_constant: float
) -> None:
    assert valve_lag_step(start, goal, H, RISE, FALL) == pytest.approx(
        closed_form(start, goal, time_constant), rel=1e-12, abs=1e-300
    )


@given(
    st.floats(-50.0, 50.0, allow_subnormal=True),
    st.floats(-50.0, 50.0, allow_subnormal=True),
)
def test_the_mean_lies_between_start_and_end_and_the_end_between_start_and_goal(
    start: float, goal: float
) -> None:
    end, mean = valve_lag_step(start, goal, H, RISE, FALL)
    assert min(start, goal) <= end <= max(start, goal)
    tolerance = 1e-12 * (abs(start) + abs(goal))
    assert min(start, end) - tolerance <= mean <= max(start, end) + tolerance


def test_time_constants_from_response_times_by_hand() -> None:
    # 90 % of a step after 3 T: T = t / ln(10); the paper's valve (50 ms, 25 ms).
    rise, fall = valve_time_constants_from_response_times(0.050, 0.025)
    assert (rise, fall) == pytest.approx((0.050 / math.log(10.0), 0.025 / math.log(10.0)), rel=1e-15)
    # 63.2 % (1 - 1/e) after exactly T; 50 % after T ln 2.
    assert valve_time_constants_from_response_times(2.0, 0.5, 1.0 - math.exp(-1.0)) == pytest.approx(
        (2.0, 0.5), rel=1e-15
    )
    assert valve_time_constants_from_response_times(0.3, 0.2, 0.5) == pytest.approx(
        (0.3 / math.log(2.0), 0.2 / math.log(2.0)), rel=1e-15
    )


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        ((0.0, 0.025), "rise_time must be a finite number > 0 s, got 0.0"),
        ((0.5, 0.025), None),  # a response time below 1 s is fine
        ((math.inf, 0.025), "rise_time must be a finite number > 0 s, got inf"),
        ((-0.1, 0.025), "rise_time must be a finite number > 0 s, got -0.1"),
        ((0.05, 0.0), "fall_time must be a finite number > 0 s, got 0.0"),
        ((0.05, math.nan), "fall_time must be a finite number > 0 s, got nan"),
        ((0.05, 0.025, 0.0), "reached_fraction must be in (0, 1), got 0.0"),
        ((0.05, 0.025, 1.0), "reached_fraction must be in (0, 1), got 1.0"),
        ((0.05, 0.025, 1.5), "reached_fraction must be in (0, 1), got 1.5"),
        ((0.05, 0.025, 0.999), None),
    ],
)
def test_time_constants_refuse_what_has_no_first_order_reading(
    arguments: tuple[float, ...], message: str | None
) -> None:
    if message is None:
        rise, fall = valve_time_constants_from_response_times(*arguments)
        assert rise > 0.0 and fall > 0.0
        return
    with pytest.raises(ValueError) as error:
        valve_time_constants_from_response_times(*arguments)
    assert str(error.value) == message


def test_a_hold_exactly_at_the_goal_stays_there() -> None:
    for start in (3.0, -3.0):
        assert valve_lag_step(start, start, H, RISE, FALL) == (start, start)


@pytest.mark.parametrize(
    ("start", "end", "time_constant"),
    [
        (0.0, 2.0, RISE),  # opening from null: the goal is the end over the share of the step reached
        (0.0, -2.0, RISE),
        (1.0, 3.0, RISE),  # opening further
        (3.0, 1.0, FALL),  # closing
        (3.0, -2.0, FALL),  # reversing: closes through null
        (-3.0, 2.0, FALL),
    ],
)
def test_valve_lag_goal_by_hand(start: float, end: float, time_constant: float) -> None:
    h = 0.005
    expected = start + (end - start) / (1.0 - math.exp(-h / time_constant))
    assert valve_lag_goal(start, end, h, RISE, FALL) == pytest.approx(expected, rel=1e-14)


@given(
    st.floats(-50.0, 50.0, allow_subnormal=True),
    st.floats(-50.0, 50.0, allow_subnormal=True),
    st.floats(1e-4, 0.05),
)
def test_valve_lag_goal_takes_the_valve_to_the_end_in_h(start: float, end: float, h: float) -> None:
    reached, _mean = valve_lag_step(start, valve_lag_goal(start, end, h, RISE, FALL), h, RISE, FALL)
    assert reached == pytest.approx(end, rel=1e-9, abs=1e-9)


def test_valve_lag_goal_of_a_step_too_short_to_move_the_valve_is_infinite() -> None:
    assert valve_lag_goal(1.0, 2.0, 5e-324, RISE, FALL) == math.inf
    assert valve_lag_goal(1.0, -2.0, 5e-324, RISE, FALL) == -math.inf
    assert valve_lag_goal(1.0, 1.0, 5e-324, RISE, FALL) == 1.0
