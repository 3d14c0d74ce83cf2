"""identify's pieces: the torque of a pulse from its motion against an analytic reference, the bag it keeps,
the settings it refuses; identify on drawn benches is in test_commission.py."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from smm_bag.reader import BagReader
from smm_commissioning.closed import LoopRecord
from smm_commissioning.identify import IdentifyConfig, pulse_torque, write_bag

from smm_dynamics import SMMParameters, mass_matrix

PERIOD = 1e-3


def _constant_torque_motion(torque: float, ticks: int, model: SMMParameters, joint: int) -> np.ndarray:
    """q (ticks, 2) of ``joint`` from rest at q = 0 under a constant torque against viscous friction
    (beta at 0: no gravity, alpha's inertia constant): q = (T / f) (t - tau (1 - exp(-t / tau)))."""
    inertia = float(mass_matrix(np.zeros(2), model)[joint, joint])
    friction = model.viscous_friction[joint]
    tau = inertia / friction
    t = np.arange(ticks) * PERIOD
    q = np.zeros((ticks, 2))
    q[:, joint] = torque / friction * (t - tau * (1.0 - np.exp(-t / tau)))
    return q


@pytest.mark.parametrize("torque", [0.003, -0.012, 0.04])
def test_the_torque_of_a_pulse_is_that_of_its_motion(torque: float) -> None:
    model = dataclasses.replace(SMMParameters(), mass_lever=0.0)
    q = _constant_torque_motion(torque, 351, model, 0)
    found = pulse_torque(q, 0, model, period=PERIOD, settle=120, half=25)
    assert found == pytest.approx(torque, rel=2e-3)


def test_a_joint_that_does_not_move_carries_its_gravity_load() -> None:
    """Held still at beta = 0.05 rad, the torque on beta is the gravity the oil holds: G(q)."""
    model = SMMParameters()
    q = np.tile([0.0, 0.05], (351, 1))
    expected = -model.gravity_sign * model.mass_lever * model.gravity * math.sin(0.05)
    assert pulse_torque(q, 1, model, period=PERIOD, settle=120, half=25) == pytest.approx(expected, rel=1e-9)


def test_the_run_is_kept_as_a_bag_with_the_measured_torque(tmp_path: Path) -> None:
    n = 50
    t = np.arange(n, dtype=np.int64) * 1_000_000
    record = LoopRecord(
        t_ns=t,
        reference=np.zeros((n, 3, 2)),
        position=np.zeros((n, 2)),
        effort=np.ones((n, 2)),
        measured=np.full((n, 2), 0.5),
        command=np.zeros((n, 2)),
        codes=np.zeros((n, 2), dtype=np.int64),
    )
    with BagReader(write_bag(record, tmp_path / "bag")) as reader:
        counts: dict[str, int] = {}
        for message in reader.messages():
            name = message.topic.rsplit("/", 1)[-1]
            counts[name] = counts.get(name, 0) + 1
    assert counts == {"joint_states": n, "reference": n, "torque_command": n, "hw_bridge_internals": n}


@pytest.mark.parametrize(
    "values, field",
    [
        ({"edge_ticks": 200, "settle_ticks": 120, "velocity_ticks": 25}, "edge_ticks"),
        ({"edge_open": 1}, "edge_open"),
        ({"bootstrap": 5}, "bootstrap"),
        ({"window": 0.0}, "window"),
    ],
)
def test_invalid_identify_settings_are_refused(values: dict[str, int | float], field: str) -> None:
    with pytest.raises(ValueError, match=field):
        IdentifyConfig(**values)  # type: ignore[arg-type]


def test_the_measured_torque_goes_with_one_run_only(tmp_path: Path) -> None:
    from smm_analysis.closed_loop import run_closed_loop
    from smm_analysis.runs.from_trajectory import write_trajectory_bag
    from smm_analysis.scenarios import get_scenario

    run = run_closed_loop(get_scenario("step").with_duration(0.01), "pid")
    measured = np.zeros((run.t_ns.size, 2))
    with pytest.raises(ValueError, match="measured_torque is written for one run"):
        write_trajectory_bag(run, tmp_path / "bag", measured_torque=measured, repeat=2)
