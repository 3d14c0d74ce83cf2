"""smm_dynamics.valve: the first-order valve lag against its closed form."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_dynamics.valve import valve_lag_step

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
