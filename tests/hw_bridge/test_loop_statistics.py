"""Loop statistics: periodicity and execution time against numpy on the same series."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from smm_hw_bridge.loop_statistics import LoopStatistics, RunningFigures


@given(st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=200))
def test_running_figures_equal_numpy(values: list[float]) -> None:
    figures = RunningFigures()
    for value in values:
        figures.add(value)
    assert figures.count == len(values)
    assert math.isclose(figures.mean, float(np.mean(values)), rel_tol=1e-9, abs_tol=1e-6)
    assert figures.minimum == min(values) and figures.maximum == max(values)
    expected_std = float(np.std(values)) if len(values) > 1 else 0.0
    assert math.isclose(figures.std, expected_std, rel_tol=1e-6, abs_tol=1e-6)


@given(st.lists(st.tuples(st.integers(1, 5_000_000), st.integers(0, 2_000_000)), min_size=2, max_size=300))
def test_periods_are_between_receptions_and_execution_is_receive_to_send(
    steps: list[tuple[int, int]],
) -> None:
    statistics = LoopStatistics()
    rx = 0
    receptions, executions = [], []
    for gap, execution in steps:
        rx += gap
        statistics.on_tick(rx, rx + execution)
        receptions.append(rx)
        executions.append(execution / 1e3)
    periods = np.diff(receptions) / 1e3
    assert statistics.period_us.count == len(periods)
    assert math.isclose(statistics.period_us.mean, float(np.mean(periods)), rel_tol=1e-9)
    assert statistics.period_us.maximum == float(np.max(periods))
    assert statistics.execution_us.minimum == min(executions)
    ordered = sorted(executions)
    assert statistics.execution_percentile_us(99) == ordered[math.ceil(0.99 * len(ordered)) - 1]
    assert statistics.execution_percentile_us(50) == ordered[math.ceil(0.5 * len(ordered)) - 1]


def test_values_name_ros2_controls_figures_and_reset_forgets_them() -> None:
    statistics = LoopStatistics()
    assert statistics.values()["periodicity.mean_us"] == "nan"
    assert math.isnan(statistics.execution_percentile_us(50))
    statistics.on_tick(1_000_000, 1_150_000)
    statistics.on_tick(2_000_000, 2_250_000)
    values = statistics.values()
    assert values["periodicity.samples"] == "1" and values["periodicity.mean_us"] == "1000.0"
    assert values["execution_time.max_us"] == "250.0" and values["execution_time.min_us"] == "150.0"
    statistics.reset()
    assert statistics.values()["execution_time.samples"] == "0"
