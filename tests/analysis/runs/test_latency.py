"""Loop latency: quantiles and CDF against hand-computed values; its figure is one distribution panel."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_analysis.runs import plots
from smm_analysis.runs.latency import latency_cdf, summarize_latency
from smm_analysis.runs.recorded import RecordedRun
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


def _run(latency_ms: list[float] | None, label: str = "run") -> RecordedRun:
    n = 4
    return RecordedRun(
        bag=Path(f"/bags/{label}"),
        manifest=RunManifest(),
        t_ns=np.arange(n, dtype=np.int64) * MS,
        reference=np.zeros((n, 3, 2)),
        position=np.zeros((n, 2)),
        position_source="ground truth",
        measured_position=np.zeros((n, 2)),
        command_torque=np.zeros((n, 2)),
        applied_torque=None,
        disturbance_estimate=None,
        latency_ns=None if latency_ms is None else np.array([round(v * MS) for v in latency_ms], np.int64),
    )


def test_latency_figure_is_one_panel_with_p50_and_p99_marked() -> None:
    figure = plots._latency_figure([_run([1.0, 2.0, 3.0, 4.0])])
    assert figure is not None
    (axis,) = figure.axes
    marks = sorted(float(line.get_xdata()[0]) for line in axis.lines if line.get_linestyle() in ("--", ":"))
    assert marks == [2.5, pytest.approx(3.97)]
    assert any("p99" in text.get_text() for text in axis.get_legend().get_texts())
    plt.close(figure)


def test_no_latency_figure_without_latency(tmp_path: Path) -> None:
    assert plots._latency_figure([_run(None)]) is None
    written = plots.write_plots([_run(None)], tmp_path)
    assert written["latency"] == "not recorded in these bags"
    written = plots.write_plots([_run([1.0, 1.0, 2.0, 9.0])], tmp_path)
    assert Path(written["latency"]).stat().st_size > 1000
