"""The excite scenario: not a paper scenario (the reproduction keeps its three), runs in closed loop."""

from __future__ import annotations

import numpy as np
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.scenarios import ALL_SCENARIOS, SCENARIOS, get_scenario
from smm_controller.excitation import ExcitationReference


def test_excite_is_known_but_not_a_paper_scenario() -> None:
    assert tuple(SCENARIOS) == ("step", "case1", "case2")
    assert tuple(ALL_SCENARIOS) == ("step", "case1", "case2", "excite")
    scenario = get_scenario("excite")
    assert scenario.reference() == ExcitationReference()
    assert scenario.duration > ExcitationReference().duration  # ends at rest with time to settle
    assert scenario.inertia_scale == 1.1 and scenario.disturbance == "none"


def test_fpdeso_tracks_the_excitation_in_closed_loop() -> None:
    run = run_closed_loop(get_scenario("excite").with_duration(3.0), "fpdeso", record_internals=False)
    amplitude = np.abs(run.desired_position).max(axis=0)
    assert np.all(amplitude > 0.1)
    assert np.all(np.sqrt(np.mean(run.tracking_error**2, axis=0)) < 0.05 * amplitude)
