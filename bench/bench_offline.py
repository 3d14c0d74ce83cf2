"""Offline closed loop speed: case2 (5 s at 1 kHz) with FPDESO, as ``smm-reproduce`` runs it.

Run by ``make bench``. Prints the wall time and real-time factor (simulated time / wall time; target
>= 20x) of ``run_closed_loop`` with and without recording the chain internals, and the per-step time
split between the plant (measure + RK4 step) and the control chain, from a hand-timed loop in the same
order. Also the time of one bare ``smm_dynamics.rk4_step``. Best of a few repeats, since the machine is
shared; nothing asserts on time.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np
from smm_analysis.closed_loop import build_chain, run_closed_loop, scenario_plant_config
from smm_analysis.scenarios import SCENARIOS
from smm_sim.plant import SimulatedPlant

from smm_dynamics import SMMParameters, rk4_step

TARGET_REAL_TIME_FACTOR = 20.0
REPEATS = 3


def best_wall_time(record_internals: bool) -> float:
    """Best wall time (s) of the full case2 FPDESO run over REPEATS runs."""
    best = float("inf")
    for _ in range(REPEATS):
        start = time.perf_counter()
        run_closed_loop("case2", "fpdeso", record_internals=record_internals)
        best = min(best, time.perf_counter() - start)
    return best


def split_per_step() -> tuple[float, float, int]:
    """Median time per step (s) of the plant part and of the chain part, and the step count."""
    scenario = SCENARIOS["case2"]
    plant = SimulatedPlant(scenario_plant_config(scenario))
    chain = build_chain("fpdeso", SMMParameters())
    period = 1e-3
    steps = round(scenario.duration / period) + 1
    references = scenario.reference().sample(np.arange(steps) * period).tolist()
    plant_times: list[float] = []
    chain_times: list[float] = []
    for k in range(steps):
        start = time.perf_counter()
        sample = plant.measure()
        y = (float(sample.position[0]), float(sample.position[1]))
        effort = (float(sample.applied_torque[0]), float(sample.applied_torque[1]))
        middle = time.perf_counter()
        tau = chain.step_floats(y, effort, references[k], period)
        after_chain = time.perf_counter()
        plant.step(tau, period)
        end = time.perf_counter()
        chain_times.append(after_chain - middle)
        plant_times.append((middle - start) + (end - after_chain))
    return statistics.median(plant_times), statistics.median(chain_times), steps


def rk4_time() -> float:
    """Median time (s) of one single-sample rk4_step."""
    params = SMMParameters()
    q, qd, tau = np.array([0.3, 0.2]), np.array([0.5, -0.4]), np.array([1.0, -1.0])
    times = []
    for _ in range(5000):
        start = time.perf_counter()
        rk4_step(q, qd, tau, 1e-3, params)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> int:
    """Prints the figures; returns 0."""
    simulated = SCENARIOS["case2"].duration
    print("offline closed loop, case2 (5 s at 1 kHz, noise, eq. 46, +10 % inertia), FPDESO")
    for record in (False, True):
        wall = best_wall_time(record)
        factor = simulated / wall
        label = "with internals   " if record else "without internals"
        print(
            f"  run_closed_loop {label}: {wall:6.3f} s wall, real-time factor {factor:5.1f}x "
            f"(target >= {TARGET_REAL_TIME_FACTOR:g}x: {factor / TARGET_REAL_TIME_FACTOR:.2f} of target)"
        )
    plant, chain, steps = split_per_step()
    total = plant + chain
    print(f"  per step (median of {steps}): plant {1e6 * plant:6.1f} us, chain {1e6 * chain:6.1f} us, ")
    print(f"    sum {1e6 * total:6.1f} us = real-time factor {1e-3 / total:5.1f}x of the bare loop")
    print(f"    shares: plant {100 * plant / total:4.1f} %, chain {100 * chain / total:4.1f} %")
    print(f"  one smm_dynamics.rk4_step (single sample): {1e6 * rk4_time():6.1f} us")
    return 0


if __name__ == "__main__":
    sys.exit(main())
