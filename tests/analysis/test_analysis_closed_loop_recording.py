"""What run_closed_loop records equals a hand-written loop on plant.measure() and plant.ground_truth."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from smm_analysis.closed_loop import run_closed_loop, scenario_plant_config
from smm_analysis.scenarios import SCENARIOS
from smm_controller.laws import PAPER_LAWS
from smm_sim.plant import SimulatedPlant

from smm_controller import make_chain
from smm_dynamics import SMMParameters

SHORT_CASE2 = SCENARIOS["case2"].with_duration(1.05)  # crosses the eq. 46 onset at 1 s
DT = 1e-3


@pytest.mark.parametrize("controller", [PAPER_LAWS[0], PAPER_LAWS[2]])
def test_every_recorded_signal_equals_the_documented_loop(controller: str) -> None:
    run = run_closed_loop(SHORT_CASE2, controller, seed=4)
    plant = SimulatedPlant(scenario_plant_config(SHORT_CASE2, seed=4))
    chain = make_chain(controller, SMMParameters())
    reference = SHORT_CASE2.reference()
    measured, position, velocity, command, applied, disturbance, estimate = ([] for _ in range(7))
    internals: dict[str, list[np.ndarray]] = {}
    for k in range(run.t_ns.size):
        sample, truth = plant.measure(), plant.ground_truth
        tau = chain.step(sample.position, sample.applied_torque, reference.evaluate(run.t_ns[k] / 1e9), DT)
        measured.append(sample.position)
        position.append(truth.position)
        velocity.append(truth.velocity)
        disturbance.append(truth.disturbance_torque)
        command.append(tau)
        if k > 0:
            applied.append(truth.applied_torque)
        for key, value in chain.internals.items():
            internals.setdefault(key, []).append(value)
        estimate.append(chain.internals["disturbance_estimate"])
        plant.step(tau, DT)
    applied.append(plant.ground_truth.applied_torque)
    expected = {
        "measured_position": measured,
        "position": position,
        "velocity": velocity,
        "command_torque": command,
        "applied_torque": applied,
        "disturbance_torque": disturbance,
        "disturbance_estimate": estimate,
    }
    for name, rows in expected.items():
        array = getattr(run, name)
        assert array.flags.c_contiguous, name
        assert_array_equal(array, np.array(rows), err_msg=name)
    assert list(run.internals) == list(internals)
    for key, rows in internals.items():
        assert_array_equal(run.internals[key], np.array(rows), err_msg=key)
    assert np.any(run.disturbance_torque != 0.0)  # the eq. 46 onset is inside the run


def test_without_internals_the_estimate_is_zero_and_nothing_else_changes() -> None:
    recorded = run_closed_loop(SHORT_CASE2, "fpdeso", seed=2)
    bare = run_closed_loop(SHORT_CASE2, "fpdeso", seed=2, record_internals=False)
    assert bare.internals == {}
    assert_array_equal(bare.disturbance_estimate, np.zeros_like(recorded.disturbance_estimate))
    assert np.any(recorded.disturbance_estimate != 0.0)
    for name in ("measured_position", "position", "velocity", "command_torque", "applied_torque"):
        assert_array_equal(getattr(bare, name), getattr(recorded, name), err_msg=name)
