"""Loop latency: quantiles and CDF against hand-computed values; its figure is one distribution panel."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from analysis.runs.block_helpers import step_block
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_analysis.runs import plots
from smm_analysis.runs.latency import SKETCH_RELATIVE_ERROR, LatencySketch, latency_cdf, summarize_latency
from smm_bag.manifest import RunManifest

MS = 1_000_000


def test_quantiles_of_one_to_a_hundred_ms() -> None:
    summary = summarize_latency(np.arange(1, 101, dtype=np.int64) * MS)
    assert summary.p50_ms == 50.5  # mean of the 50th and 51st values
    assert summary.p99_ms == pytest.approx(99.01, abs=1e-12)  # 99 + 0.01 * (100 - 99), linear interpolation
    assert summary.max_ms == 100.0


def test_cdf_is_sorted_and_ends_at_one() -> None:
    values, fraction = latency_cdf(np.array([3, 1, 2, 2], dtype=np.int64) * MS)
    np.testing.assert_array_equal(values, [1.0, 2.0, 2.0, 3.0])
    np.testing.assert_array_equal(fraction, [0.25, 0.5, 0.75, 1.0])


@given(st.lists(st.integers(0, 10**9), min_size=1, max_size=200))
def test_p50_and_p99_sit_where_the_cdf_reaches_them(latencies: list[int]) -> None:
    latency_ns = np.array(latencies, dtype=np.int64)
    values, fraction = latency_cdf(latency_ns)
    summary = summarize_latency(latency_ns)
    assert values[0] <= summary.p50_ms <= summary.p99_ms <= summary.max_ms == values[-1]
    assert fraction[np.searchsorted(values, summary.p50_ms, side="right") - 1] >= 0.5


@pytest.mark.parametrize("bad", [np.array([], dtype=np.int64), np.zeros((2, 2), dtype=np.int64)])
def test_empty_or_two_dimensional_latency_is_refused(bad: np.ndarray) -> None:
    with pytest.raises(ValueError, match="latency_ns must be a non-empty 1-D array"):
        summarize_latency(bad)
    with pytest.raises(ValueError, match="latency_ns must be a non-empty 1-D array"):
        latency_cdf(bad)


def _figures(latency_ms: list[float] | None, label: str = "run") -> plots.RunFigures:
    """A run's figures fed one block of 4 steps with these latencies (none fed when None)."""
    figures = plots.RunFigures(label, RunManifest(), "ground truth")
    if latency_ms is not None:
        figures.add(
            step_block(np.arange(4, dtype=np.int64) * MS, latency_ns=[round(v * MS) for v in latency_ms])
        )
    return figures


def test_latency_figure_is_one_panel_with_p50_and_p99_marked() -> None:
    figure = plots._latency_figure([_figures([1.0, 2.0, 3.0, 4.0])])
    assert figure is not None
    (axis,) = figure.axes
    marks = sorted(
        float(np.asarray(line.get_xdata())[0]) for line in axis.lines if line.get_linestyle() in ("--", ":")
    )
    # numpy's 2.5 and 3.97 ms, within the sketch's relative bound
    assert marks == [
        pytest.approx(2.5, rel=SKETCH_RELATIVE_ERROR),
        pytest.approx(3.97, rel=SKETCH_RELATIVE_ERROR),
    ]
    legend = axis.get_legend()
    assert legend is not None
    assert any("p99" in text.get_text() for text in legend.get_texts())
    plt.close(figure)


def test_no_latency_figure_without_latency(tmp_path: Path) -> None:
    assert plots._latency_figure([_figures(None)]) is None
    written = plots.write_plots([_figures(None)], tmp_path)
    assert written["latency"] == "not recorded in these bags"
    written = plots.write_plots([_figures([1.0, 1.0, 2.0, 9.0])], tmp_path)
    assert Path(written["latency"]).stat().st_size > 1000


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.one_of(st.integers(-2_000, 2_000), st.integers(1_000, 10**10), st.integers(-(10**9), -1_000)),
        min_size=1,
        max_size=300,
    ),
    st.sampled_from([0.0, 0.01, 0.5, 0.99, 1.0]),
    st.integers(1, 5),
)
def test_the_sketch_quantiles_are_within_the_stated_bound_of_numpy(
    values: list[int], p: float, pieces: int
) -> None:
    latency = np.array(values, dtype=np.int64)
    sketch = LatencySketch()
    for part in np.array_split(latency, pieces):
        sketch.add(part)
    ordered = np.sort(latency)
    rank = p * (latency.size - 1)
    neighbours = ordered[[int(np.floor(rank)), int(np.ceil(rank))]]
    bound = SKETCH_RELATIVE_ERROR * float(np.max(np.abs(neighbours))) * (1 + 1e-9) / 1e6
    exact = float(np.percentile(latency.astype(np.float64), 100 * p)) / 1e6
    assert abs(sketch.quantile_ms(p) - exact) <= bound + 1e-15
    assert sketch.count == latency.size
    assert sketch.summary().max_ms == latency.max() / 1e6  # exact


def test_small_latencies_are_counted_exactly_and_the_buckets_stay_few() -> None:
    sketch = LatencySketch()
    sketch.add(np.array([-3, 0, 5, 999], dtype=np.int64))
    assert [sketch.quantile_ms(p) for p in (0.0, 1 / 3, 2 / 3, 1.0)] == [-3e-6, 0.0, 5e-6, 999e-6]
    sketch.add(np.arange(1_000, 10**9, 997, dtype=np.int64))  # a million values from 1 us to 1 s
    assert len(sketch.counts) < 4 + math.log(1e6) / math.log(1.002) + 2
