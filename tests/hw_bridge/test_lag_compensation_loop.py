"""The valve-lag compensation at 200 and 100 Hz: case 1 on the emulated bench (the paper's valve) in lockstep.

One process (tests/lockstep_case1.py: the board core and the bridge core, the FPDESO chain at the rate's
settings), against the lagless simulator at the same rate (the offline loop). Without the compensation
(``bridge.valve.lag_compensation: off``) 200 Hz tracks beta about 15x worse and 100 Hz ends in the runaway
safety stop (docs/LAUNCH.md, "Control rate").
"""

from __future__ import annotations

import numpy as np
import pytest
from lockstep_case1 import SETTLED, case1, rms
from smm_analysis.closed_loop import run_closed_loop
from smm_bench_emulator.bench_file import default_bench
from smm_bringup.graph import control_rate_configs
from smm_controller.fpdeso import FPDESOController
from smm_hw_bridge.core import BridgeConfig

from smm_dynamics import SMMParameters


@pytest.mark.parametrize(("divider", "bound"), [(5, 1.3), (10, 1.3)], ids=["200Hz", "100Hz"])
def test_case1_on_the_lagging_bench_tracks_as_the_lagless_simulator(divider: int, bound: float) -> None:
    td, law = control_rate_configs(1000 // divider)
    simulator = run_closed_loop(
        "case1",
        "fpdeso",
        control_period=divider * 1e-3,
        substeps=divider,
        td_config=td,
        controller=FPDESOController(law, SMMParameters()),
        record_internals=False,
    )
    lagless = rms(simulator.tracking_error[SETTLED // divider :])
    errors, peak = case1(default_bench(), BridgeConfig(lockstep=True, control_divider=divider))  # no stop
    assert default_bench().plant.valve_time_constants == pytest.approx((0.0217, 0.0109), abs=1e-4)
    ratio = rms(errors[SETTLED:]) / lagless
    assert np.all(ratio < bound), (ratio, lagless)
    assert peak < 1.1  # case 1's amplitude is 1 rad
