"""The table of metrics: each name once, the result types and consumers read it, reductions as documented."""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_analysis.batch import INDEX_NAMES
from smm_analysis.errors import MetricsInputError
from smm_analysis.metrics import (
    METRICS,
    AxisError,
    Group,
    JointIndices,
    Reduction,
    StepMetrics,
    metric,
    metrics_of,
)
from smm_analysis.reproduction.metrics_json import METRICS_UNITS

RESULT_TYPES = {Group.JOINT: JointIndices, Group.STEP: StepMetrics, Group.END_EFFECTOR: AxisError}


def test_each_metric_is_named_once_and_each_result_type_holds_exactly_its_groups_metrics() -> None:
    names = [row.name for row in METRICS]
    assert len(names) == len(set(names))
    for group, result in RESULT_TYPES.items():
        assert [item.name for item in fields(result)] == [row.name for row in metrics_of(group)]


def test_batched_columns_and_units_come_from_the_table() -> None:
    batched = [row for row in METRICS if row.batched]
    assert tuple(f"{row.column}_{joint}" for row in batched for joint in ("alpha", "beta")) == INDEX_NAMES
    assert len(set(INDEX_NAMES)) == len(INDEX_NAMES)
    assert all(row.group is not Group.END_EFFECTOR for row in batched)  # the batched loop has no kinematics
    for row in METRICS:
        key = "end_effector" if row.group is Group.END_EFFECTOR else row.name
        assert METRICS_UNITS[key] == row.json_unit


def test_a_step_metric_is_no_reduction_of_one_series_and_an_unknown_name_is_refused() -> None:
    with pytest.raises(MetricsInputError, match="rise_time"):
        metric("rise_time").of(np.array([0, 1]), np.array([0.0, 1.0]))
    with pytest.raises(KeyError, match="known: Ma"):
        metric("nope")


def _streamed(reduction: Reduction, t_ns: np.ndarray, series: np.ndarray) -> float:
    """The reduction one sample at a time, keeping only the state its docstring names."""
    t_s = (t_ns - t_ns[0]) / 1e9
    peak = total = squares = increments = 0.0
    previous: float | None = None
    for k, value in enumerate(series):
        peak = max(peak, abs(value))
        total += abs(value)
        if previous is not None:
            squares += (previous**2 + value**2) * (t_s[k] - t_s[k - 1]) / 2
            increments += (value - previous) ** 2
        previous = value
    count = series.size
    return {
        Reduction.MAX_ABS: peak,
        Reduction.MEAN_ABS: total / count,
        Reduction.RMS_OVER_TIME: math.sqrt(squares / t_s[-1]),
        Reduction.INTEGRAL_SQUARE: squares,
        Reduction.INCREMENT_RMS: math.sqrt(increments / (count - 1)),
    }[reduction]


@given(
    steps=st.lists(st.integers(1, 10**9), min_size=1, max_size=30),
    values=st.lists(st.floats(-1e3, 1e3), min_size=31, max_size=31),
)
@settings(max_examples=40, deadline=None)
def test_each_reduction_equals_its_streamed_definition(steps: list[int], values: list[float]) -> None:
    t_ns = np.concatenate([[0], np.cumsum(steps)]).astype(np.int64)
    series = np.asarray(values[: t_ns.size])
    for row in METRICS:
        if row.function is not None:
            expected = _streamed(row.reduction, t_ns, series)
            assert row.of(t_ns, series) == pytest.approx(expected, rel=1e-9, abs=1e-9), row.name
