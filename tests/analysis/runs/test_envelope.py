"""runs.envelope and figures: columns bounded whatever the length, a spike survives, one figure at a time."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from analysis.runs.block_helpers import step_block
from matplotlib.figure import Figure
from smm_analysis.runs.envelope import Envelope
from smm_analysis.runs.plots import RunFigures, _figure, write_plots
from smm_bag.manifest import RunManifest


def test_columns_stay_bounded_and_hold_every_extreme() -> None:
    envelope = Envelope(columns=64)
    rng = np.random.default_rng(3)
    values = rng.normal(size=100_003)
    t_s = np.arange(values.size, dtype=np.float64) * 1e-3
    for start in range(0, values.size, 4099):  # blocks that do not divide the columns
        envelope.add(t_s[start : start + 4099], {"v": values[start : start + 4099]})
    assert envelope.used <= 64 and envelope.width == 2048
    x, y = envelope.line("v")
    assert np.nanmax(y) == values.max() and np.nanmin(y) == values.min()
    assert x[0] == 0.0 and x[-1] == t_s[-1]
    # Each column holds exactly the min and max of its steps.
    low, high = envelope.low["v"][: envelope.used], envelope.high["v"][: envelope.used]
    for column in (0, 17, envelope.used - 1):
        steps = values[column * envelope.width : (column + 1) * envelope.width]
        assert (low[column], high[column]) == (steps.min(), steps.max())


def test_nan_steps_are_ignored_and_a_series_may_start_late() -> None:
    envelope = Envelope(columns=8)
    envelope.add(np.arange(4.0), {"a": np.array([1.0, np.nan, 3.0, 2.0])})
    envelope.add(np.arange(4.0, 8.0), {"a": np.full(4, np.nan), "b": np.array([5.0, 6.0, 7.0, 8.0])})
    assert envelope.drawn("a") and envelope.drawn("b")
    _, a = envelope.line("a")
    assert np.nanmax(a) == 3.0 and np.all(np.isnan(a[8:]))
    _, b = envelope.line("b")
    assert np.all(np.isnan(b[:8])) and np.nanmax(b) == 8.0


def test_bad_column_counts_are_refused() -> None:
    for columns in (0, 3):
        with pytest.raises(ValueError, match="columns"):
            Envelope(columns=columns)


def test_a_one_step_spike_in_an_hour_of_steps_reaches_the_figure() -> None:
    figures = RunFigures("run", RunManifest(), "ground truth")
    steps, size, spike = 3_600_000, 100_000, 1_234_567  # an hour at 1 kHz, in blocks
    for start in range(0, steps, size):
        t_ns = (np.arange(start, start + size, dtype=np.int64)) * 1_000_000
        torque = np.zeros((size, 2))
        if start <= spike < start + size:
            torque[spike - start, 1] = 42.0
        figures.add(step_block(t_ns, torque=torque, first_step=start))
    figure = _figure([figures], "torque")
    assert figure is not None
    beta = figure.axes[1]
    drawn = np.concatenate([np.asarray(line.get_ydata(), dtype=np.float64) for line in beta.lines])
    assert np.nanmax(drawn) == 42.0
    assert max(np.asarray(line.get_xydata()).shape[0] for line in beta.lines) <= 2 * 2048


def test_figures_are_written_one_at_a_time(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    figures = RunFigures("run", RunManifest(), "ground truth")
    size = 5000
    figures.add(step_block(np.arange(size, dtype=np.int64) * 1_000_000, torque=np.ones((size, 2))))
    open_at_save: list[int] = []
    open_before = len(plt.get_fignums())
    save = Figure.savefig

    def counting_save(self: Figure, *args: object, **kwargs: object) -> None:
        open_at_save.append(len(plt.get_fignums()))
        save(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Figure, "savefig", counting_save)
    written = write_plots([figures], tmp_path)
    assert sum(path.endswith(".png") for path in written.values()) == len(open_at_save) >= 3
    assert max(open_at_save) == open_before + 1  # one canvas at a time, not seven
