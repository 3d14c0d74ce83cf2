"""Scenarios of SPEC section 3 as data."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from smm_analysis.errors import UnknownScenarioError
from smm_analysis.scenarios import SCENARIOS, Scenario, get_scenario


def test_the_three_paper_scenarios() -> None:
    assert list(SCENARIOS) == ["step", "case1", "case2"]
    step, case1, case2 = SCENARIOS["step"], SCENARIOS["case1"], SCENARIOS["case2"]
    assert (step.duration, case1.duration, case2.duration) == (1.0, 5.0, 5.0)
    assert step.is_step and not case1.is_step and not case2.is_step
    for scenario in (step, case1):
        assert scenario.noise_std == (0.0, 0.0)
        assert scenario.disturbance == "none"
        assert scenario.inertia_scale == 1.0
    assert case2.noise_std == (0.001, 0.001)
    assert case2.disturbance == "eq46"
    assert case2.inertia_scale == pytest.approx(1.1)


def test_step_reference() -> None:
    reference = SCENARIOS["step"].reference().sample(np.array([0.0, 0.5]))
    assert_allclose(reference[:, 0, :], [[1.0, 0.785], [1.0, 0.785]])
    assert_allclose(reference[:, 1:, :], 0.0)


def test_sine_reference_is_eq41_with_analytic_derivatives() -> None:
    t = np.linspace(0.0, 5.0, 101)
    reference = SCENARIOS["case2"].reference().sample(t)
    amplitude = np.array([1.0, 0.785])
    assert_allclose(reference[:, 0, :], np.sin(np.pi * t)[:, None] * amplitude, atol=1e-15)
    assert_allclose(reference[:, 1, :], np.pi * np.cos(np.pi * t)[:, None] * amplitude, atol=1e-14)
    assert_allclose(reference[:, 2, :], -(np.pi**2) * np.sin(np.pi * t)[:, None] * amplitude, atol=1e-13)


def test_with_duration_keeps_everything_else() -> None:
    short = SCENARIOS["case2"].with_duration(0.5)
    assert short.duration == 0.5
    assert dataclasses.replace(short, duration=5.0) == SCENARIOS["case2"]


def test_get_scenario() -> None:
    assert get_scenario("case1") is SCENARIOS["case1"]
    with pytest.raises(UnknownScenarioError, match="case3"):
        get_scenario("case3")


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("duration", 0.0),
        ("duration", math.nan),
        ("reference_kind", "ramp"),
        ("amplitude", (1.0, math.inf)),
        ("angular_frequency", -1.0),
        ("noise_std", (-0.1, 0.0)),
        ("disturbance", "wind"),
        ("inertia_scale", 0.0),
        ("name", ""),
    ],
)
def test_invalid_scenarios_are_rejected(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        dataclasses.replace(SCENARIOS["case1"], **{field: value})


def test_scenarios_are_frozen() -> None:
    scenario: Scenario = SCENARIOS["step"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        scenario.duration = 2.0  # type: ignore[misc]
