"""What a control rate below the board's tick costs: case-1 and case-2 tracking RMS at each offered rate.

Deterministic (no wall clock): the offline closed loop (``smm_analysis.closed_loop``, the chain and plant a
lockstep ``smm-launch`` run reproduces), FPDESO, the plant integrated at the board's 1 ms step (``substeps``
N at a period of N ms, each command held over its period), the settings of each rate read from its file
(``smm_controller/config/control_rate_<rate>.yaml``, the file ``smm-launch --control-rate`` applies).
``--sweep`` also runs the TD filter factor h at 2 dt, the rule's alternative. Prints the markdown table of
docs/LAUNCH.md, "Control rate":

    .venv/bin/python bench/bench_control_rate.py [--sweep]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.errors import ClosedLoopDivergedError
from smm_analysis.metrics import control_energy, rms_error
from smm_bringup.graph import control_rate_configs
from smm_hw_bridge.control_rate import BOARD_TICK_HZ, CONTROL_RATES_HZ, control_divider

from smm_controller import FPDESOController, TrackingDifferentiatorConfig
from smm_dynamics import SMMParameters

SCENARIOS = ("case1", "case2")


def measure(
    scenario: str, rate: int, td: TrackingDifferentiatorConfig
) -> tuple[np.ndarray, np.ndarray] | None:
    """(RMS alpha, beta (rad), eps_u alpha, beta) of FPDESO on ``scenario`` at ``rate``; None: diverged.

    FPDESO's gains are those of ``rate``'s file (smm_bringup.graph.control_rate_configs), the TD ``td``.
    """
    divider = control_divider(rate)
    try:
        run = run_closed_loop(
            scenario,
            "fpdeso",
            control_period=divider / BOARD_TICK_HZ,
            substeps=divider,
            td_config=td,
            controller=FPDESOController(control_rate_configs(rate)[1], SMMParameters()),
            record_internals=False,
        )
    except ClosedLoopDivergedError:
        return None
    error, torque = run.tracking_error, run.command_torque
    rms = np.array([rms_error(run.t_ns, error[:, joint]) for joint in range(2)])
    energy = np.array([control_energy(run.t_ns, torque[:, joint]) for joint in range(2)])
    return rms, energy


def main(argv: list[str] | None = None) -> int:
    """Prints the table; exit 0."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweep", action="store_true", help="also h = 2 dt at each rate below 1 kHz")
    arguments = parser.parse_args(argv)
    runs: list[tuple[int, str, TrackingDifferentiatorConfig]] = [
        (rate, "settings file" if rate != BOARD_TICK_HZ else "defaults", control_rate_configs(rate)[0])
        for rate in CONTROL_RATES_HZ
    ]
    if arguments.sweep:
        for rate in CONTROL_RATES_HZ[1:]:
            period = control_divider(rate) / BOARD_TICK_HZ
            runs.append(
                (rate, "sweep: h = 2 dt", TrackingDifferentiatorConfig(filter_factor=(2 * period,) * 2))
            )
    base: dict[str, np.ndarray] = {}
    print(
        "| rate | settings | TD h (s) | case1 RMS alpha / beta (mrad) | vs 1 kHz | "
        "case2 RMS alpha / beta (mrad) | vs 1 kHz | case2 eps_u alpha / beta |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for rate, label, td in runs:
        cells = [f"{rate} Hz", label, f"{td.filter_factor[0]:g}"]
        for scenario in SCENARIOS:
            result = measure(scenario, rate, td)
            if result is None:
                cells += ["diverged", ""]
                continue
            rms, energy = result
            if rate == BOARD_TICK_HZ and label == "defaults":
                base[scenario] = rms
            ratio = rms / base[scenario] if scenario in base else np.array([np.nan, np.nan])
            cells += [f"{1e3 * rms[0]:.2f} / {1e3 * rms[1]:.2f}", f"{ratio[0]:.2f}x / {ratio[1]:.2f}x"]
            if scenario == "case2":
                cells.append(f"{energy[0]:.2f} / {energy[1]:.2f}")
        print("| " + " | ".join(cells) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
