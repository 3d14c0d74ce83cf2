"""LatencyHistogram: the percentiles of every value added, to the microsecond, in bounded memory."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from smm_bench_emulator.latency import TOP_US, LatencyHistogram


@given(
    st.lists(st.integers(min_value=-5_000, max_value=2 * TOP_US * 1000), min_size=1, max_size=300),
    st.floats(min_value=0.0, max_value=100.0),
)
def test_percentiles_are_those_of_the_values_rounded_down_to_a_us(values: list[int], q: float) -> None:
    histogram = LatencyHistogram()
    for value in values:
        histogram.add(value)
    clipped = sorted(max(value, 0) for value in values)
    seen = clipped[max(1, math.ceil(q / 100.0 * len(clipped))) - 1]  # the inverted CDF
    expected = max(clipped) / 1e3 if seen // 1000 >= TOP_US else float(seen // 1000)
    assert histogram.count == len(values)
    assert histogram.percentile_us(q) == expected


def test_no_value_no_percentile_and_the_memory_does_not_grow() -> None:
    histogram = LatencyHistogram()
    assert histogram.percentile_us(50) is None
    size = histogram._bins.nbytes
    for value in np.arange(0, 10**9, 7919):
        histogram.add(int(value))
    assert histogram._bins.nbytes == size and histogram.count == len(range(0, 10**9, 7919))
