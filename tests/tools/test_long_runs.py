"""tools/long_runs.py: the RSS series of a long run (its figure at 10 minutes and the growth since)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

TOOL = Path(__file__).resolve().parents[2] / "tools" / "long_runs.py"


@pytest.fixture(scope="module")
def long_runs() -> ModuleType:
    spec = importlib.util.spec_from_file_location("long_runs_under_test", TOOL)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_the_growth_since_10_minutes_is_the_last_sample_less_the_first_at_10_minutes(
    long_runs: ModuleType,
) -> None:
    times = [5.0, 300.0, 600.0, 610.0, 3600.0]
    series = long_runs.RssSeries("recorder_node", 1, times, [1024, 2048, 4096, 8192, 7168])
    assert series.kib_at(600.0) == 8192  # the first sample at least 600 s after the first one (at 5 s)
    assert series.summary(60.0).endswith("end - 10 min -1.0 MiB")


def test_a_series_shorter_than_10_minutes_has_no_such_figure(long_runs: ModuleType) -> None:
    series = long_runs.RssSeries("direct_loop", 2, [0.0, 300.0, 599.0], [1024, 2048, 3072])
    assert series.kib_at(600.0) is None
    assert "10 min" not in series.summary(60.0)
    assert long_runs.RssSeries("emulator", 3).kib_at(0.0) is None
