"""tune's sweep spec: a valid smm-sweep spec on the identified plant, plants drawn within the intervals, the
paper's gains among the sets; settings it refuses. The sweep itself runs in test_commission.py."""

from __future__ import annotations

import numpy as np
import pytest
from smm_analysis.identification import PARAMETER_NAMES, parameter_vector
from smm_analysis.sweep.spec import parse_spec
from smm_commissioning.tune import TuneConfig, plant_values, tune_spec
from smm_controller.fpdeso import FPDESOConfig
from smm_hw_bridge.bridge_config import BridgeConfig

from smm_dynamics import SMMParameters


def test_the_spec_sweeps_the_gains_on_plants_drawn_within_the_intervals() -> None:
    model = SMMParameters()
    theta = parameter_vector(model)
    interval = np.stack([theta * 0.95 - 0.001, theta * 1.05 + 0.001], axis=1)
    plant = plant_values(model, BridgeConfig(), (2e-5, 2e-5))
    spec = parse_spec(tune_spec(interval, plant, TuneConfig(draws=4)))
    assert len(spec.gain_sets) == 9 and len(spec.plant_draws) == 4
    paper = FPDESOConfig().fuzzy
    assert {"fpdeso.fuzzy.kp0": list(paper.kp0), "fpdeso.fuzzy.kd0": list(paper.kd0)} in spec.gain_sets
    assert spec.fixed["model.I11"] == model.I11
    assert plant["torque_limit"] == pytest.approx([10.0, 10.0])  # the default valve: full scale 10 N m
    for draw in spec.plant_draws:
        for name, value in draw.items():
            base, _, joint = name.removeprefix("params.").partition("[")
            key = base if not joint else f"{base}.{('alpha', 'beta')[int(joint[0])]}"
            low, high = interval[PARAMETER_NAMES.index(key)]
            assert max(low, 0.0 if base != "torque_offset" else low) <= value <= high, name


def test_a_grid_without_the_papers_gains_is_refused() -> None:
    with pytest.raises(ValueError, match=r"must hold 1\.0"):
        TuneConfig(factors=(0.8, 1.25))
