"""The true lumped disturbance: model error + external, exact against the plant's own terms."""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.testing import assert_allclose
from smm_analysis.closed_loop import run_closed_loop, scenario_plant_config
from smm_analysis.lumped import recorded_lumped_disturbance, trajectory_lumped_disturbance
from smm_analysis.scenarios import get_scenario

from smm_dynamics import SMMParameters, friction_torque

SHORT_CASE2 = get_scenario("case2").with_duration(1.5)


def test_with_the_exact_inertias_the_model_error_is_the_friction() -> None:
    run = run_closed_loop(get_scenario("case1").with_duration(1.0), "fpdeso", record_internals=False)
    parts = trajectory_lumped_disturbance(run)
    assert_allclose(parts.model_error, friction_torque(run.velocity, run.plant_params), atol=1e-12)
    assert_allclose(parts.external, 0.0)
    compensated = trajectory_lumped_disturbance(run, compensate_friction=True)
    assert_allclose(compensated.model_error, 0.0, atol=1e-12)


def test_parts_add_up_and_the_external_part_is_the_scenario_model() -> None:
    run = run_closed_loop(SHORT_CASE2, "fpdeso")
    parts = trajectory_lumped_disturbance(run)
    assert_allclose(parts.total, parts.model_error + parts.external, atol=1e-15)
    assert_allclose(parts.external, run.disturbance_torque)
    assert np.abs(parts.external).max() > 0.4  # eq. 46 from t = 1 s
    # Before the onset the observer's estimate follows the model error (+10 % inertias and the friction).
    early = (run.time > 0.3) & (run.time < 1.0)
    lag = np.sqrt(np.mean((run.disturbance_estimate[early] - parts.total[early]) ** 2))
    assert lag < np.sqrt(np.mean(parts.total[early] ** 2))


def test_recorded_variant_agrees_with_the_offline_one() -> None:
    run = run_closed_loop(SHORT_CASE2, "fpdeso", record_internals=False)
    parameters = {
        "/smm/smm_sim_node": {
            **{
                f"params.{f.name}": _value(getattr(SMMParameters(), f.name))
                for f in dataclasses.fields(SMMParameters)
            },
            "inertia_scale": 1.1,
            "disturbance": "eq46",
        },
        "/smm/controller_node": {
            f"model.{f.name}": _value(getattr(SMMParameters(), f.name))
            for f in dataclasses.fields(SMMParameters)
        },
    }
    effort = np.vstack([np.zeros((1, 2)), run.applied_torque[:-1]])
    recorded = recorded_lumped_disturbance(parameters, run.time, run.position, effort)
    offline = trajectory_lumped_disturbance(run)
    assert recorded is not None
    inner = slice(5, -5)
    scale = np.abs(offline.total).max()
    # The recorded variant differentiates the ground-truth positions (no velocity in the bag).
    assert np.sqrt(np.mean((recorded.total[inner] - offline.total[inner]) ** 2)) < 0.02 * scale
    assert recorded_lumped_disturbance({}, run.time, run.position, effort) is None
    assert scenario_plant_config(SHORT_CASE2).true_params == run.plant_params


def _value(value: object) -> object:
    return list(value) if isinstance(value, tuple) else value
