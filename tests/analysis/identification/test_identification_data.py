"""Data preparation: filtering settings, and every kind of bad input refused or warned about by name."""

from __future__ import annotations

import numpy as np
import pytest
from identification_synthetic import PERIOD_NS, synthetic_run
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.errors import (
    IdentificationInputError,
    NotEnoughDataError,
    SaturatedRunError,
    StopsRunError,
)
from smm_analysis.identification import FilterSettings, prepare_run
from smm_analysis.identification.truth import prepare_trajectory
from smm_analysis.scenarios import get_scenario
from smm_sim.plant import PlantConfig


def test_prepared_run_reports_its_settings_and_uses_moving_rows() -> None:
    prepared = prepare_run("synthetic", *synthetic_run())
    text = prepared.settings.describe()
    assert "filtfilt" in text and "savgol_filter" in text and "4 Hz" in text
    assert prepared.sample_period == pytest.approx(1e-3)
    for segment in prepared.segments:
        assert np.all(np.abs(segment.velocity[segment.use]) >= prepared.settings.rest_velocity)
    assert any(
        "at rest" in warning for warning in prepared.warnings
    )  # the excitation starts and ends at rest


def test_a_missing_step_splits_the_run_into_stretches() -> None:
    t_ns, position, effort = synthetic_run()
    keep = np.ones(t_ns.size, dtype=bool)
    keep[5000] = False
    prepared = prepare_run("gap", t_ns[keep], position[keep], effort[keep])
    assert len(prepared.segments) == 2


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t, q, e: (t, q[:, :1], e), r"position must have shape"),
        (lambda t, q, e: (t, q, e[:-1]), r"torque must have shape"),
        (lambda t, q, e: (t, np.where(np.arange(q.size).reshape(q.shape) == 7, np.nan, q), e), r"NaN"),
        (lambda t, q, e: (t[::-1].copy(), q, e), r"strictly increasing"),
        (lambda t, q, e: (t.astype(float), q, e), r"integer array"),
    ],
)
def test_malformed_arrays_are_named(change: object, message: str) -> None:
    t_ns, position, effort = synthetic_run()
    with pytest.raises(IdentificationInputError, match=message):
        prepare_run("bad", *change(t_ns, position, effort))  # type: ignore[operator]


def test_a_run_too_short_is_refused() -> None:
    t_ns, position, effort = synthetic_run()
    with pytest.raises(NotEnoughDataError, match="too short"):
        prepare_run("short", t_ns[:300], position[:300], effort[:300])
    with pytest.raises(NotEnoughDataError, match=r"usable motion.*at least 2 s"):
        prepare_run("short", t_ns[:1800], position[:1800], effort[:1800])


def test_a_cutoff_above_nyquist_is_refused() -> None:
    with pytest.raises(IdentificationInputError, match="Nyquist"):
        prepare_run("fast", *synthetic_run(), settings=FilterSettings(cutoff=600.0))
    assert PERIOD_NS == 1_000_000


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"cutoff": 0.0}, "cutoff"),
        ({"order": 0}, "order"),
        ({"savgol_order": 1}, "savgol_order"),
        ({"edge": -1.0}, "edge"),
        ({"max_excluded": 0.0}, "max_excluded"),
    ],
)
def test_invalid_filter_settings_name_the_field(overrides: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=f"^{message}"):
        FilterSettings(**overrides)  # type: ignore[arg-type]


def _excite(plant: PlantConfig, duration: float = 6.0) -> object:
    return run_closed_loop(
        get_scenario("excite").with_duration(duration), "fpdeso", plant_config=plant, record_internals=False
    )


def test_a_saturated_run_is_refused_naming_saturation() -> None:
    run = _excite(PlantConfig(torque_limit=(0.3, 0.3)))
    with pytest.raises(SaturatedRunError, match=r"torque saturated .* max_excluded"):
        prepare_trajectory("saturated", run)  # type: ignore[arg-type]


def test_saturation_behind_a_valve_lag_is_found_from_the_command() -> None:
    """The lag keeps the applied torque below its limit; the command beyond it gives saturation away."""
    run = _excite(PlantConfig(torque_limit=(0.3, 0.3), valve_time_constants=(0.02, 0.02)))
    with pytest.raises(SaturatedRunError, match=r"commanded beyond it"):
        prepare_trajectory("lagged", run)  # type: ignore[arg-type]


def test_a_run_against_the_stops_is_refused_naming_the_stops() -> None:
    run = _excite(PlantConfig(joint_limits=(0.35, 0.3)))
    with pytest.raises(StopsRunError, match=r"mechanical stop .* max_excluded"):
        prepare_trajectory("stops", run)  # type: ignore[arg-type]


def test_a_short_stretch_at_a_stop_is_left_out_with_a_warning() -> None:
    run = _excite(PlantConfig(joint_limits=(0.9, 1.3)), duration=11.0)
    prepared = prepare_trajectory("touching", run, FilterSettings())  # type: ignore[arg-type]
    assert any("mechanical stop" in warning and "left out" in warning for warning in prepared.warnings)
