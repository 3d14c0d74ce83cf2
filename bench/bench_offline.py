"""Offline closed loop speed: case2 (5 s at 1 kHz) with FPDESO, as ``smm-reproduce`` runs it.

Run by ``make bench``. Prints the wall time and real-time factor (simulated time / wall time; target
>= 20x) of ``run_closed_loop`` with and without recording the chain internals, and the per-step time
split between the plant (measure + RK4 step), the control chain and the loop's own bookkeeping, from a
hand-timed loop with the same calls as ``run_closed_loop``. Also the time of one bare plant integration
step, on the float fast path the plant uses (``rk4_step_floats``) and on the array API (``rk4_step``).
Best of a few repeats and medians, since the machine is shared; nothing asserts on time.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np
from smm_analysis.closed_loop import run_closed_loop, scenario_plant_config
from smm_analysis.scenarios import SCENARIOS
from smm_controller.chain import build_chain
from smm_sim.plant import SimulatedPlant, disturbance_torque

from smm_dynamics import SMMParameters, rk4_step, rk4_step_floats

TARGET_REAL_TIME_FACTOR = 20.0
REPEATS = 5


def best_wall_time(record_internals: bool) -> float:
    """Best wall time (s) of the full case2 FPDESO run over REPEATS runs."""
    best = float("inf")
    for _ in range(REPEATS):
        start = time.perf_counter()
        run_closed_loop("case2", "fpdeso", record_internals=record_internals)
        best = min(best, time.perf_counter() - start)
    return best


def split_per_step() -> tuple[float, float, float, int]:
    """Mean time per step (s) of the plant, the chain and the bookkeeping, and the step count.

    Means, not medians: the wall time of a run is their sum. Best of REPEATS passes.
    """
    scenario = SCENARIOS["case2"]
    period = 1e-3
    steps = round(scenario.duration / period) + 1
    references = scenario.reference().sample(np.arange(steps) * period).tolist()
    best = (float("inf"), float("inf"), float("inf"))
    for _ in range(REPEATS):
        plant = SimulatedPlant(scenario_plant_config(scenario))
        chain = build_chain("fpdeso", SMMParameters())
        model = plant.config.disturbance
        plant_time = chain_time = bookkeeping_time = 0.0
        rows = []
        for k in range(steps):
            start = time.perf_counter()
            y0, y1, effort0, effort1 = plant.measure_floats()
            middle = time.perf_counter()
            tau = chain.step_floats((y0, y1), (effort0, effort1), references[k], period)
            after_chain = time.perf_counter()
            dist = disturbance_torque(model, plant.time_ns / 1e9)
            rows.append((y0, y1, *plant.state_floats, tau[0], tau[1], *dist))
            before_plant = time.perf_counter()
            plant.step(tau, period)
            end = time.perf_counter()
            plant_time += (middle - start) + (end - before_plant)
            chain_time += after_chain - middle
            bookkeeping_time += before_plant - after_chain
        if plant_time + chain_time < best[0] + best[1]:
            best = (plant_time / steps, chain_time / steps, bookkeeping_time / steps)
    return (*best, steps)


def integration_step_times() -> tuple[float, float]:
    """Median time (s) of one single-sample plant integration step: rk4_step_floats, rk4_step."""
    params = SMMParameters()
    state, torque = (0.3, 0.2, 0.5, -0.4), (1.0, -1.0)
    q, qd, tau = np.array(state[:2]), np.array(state[2:]), np.array(torque)
    fast, array = [], []
    for _ in range(5000):
        start = time.perf_counter()
        rk4_step_floats(state, torque, 1e-3, params)
        middle = time.perf_counter()
        rk4_step(q, qd, tau, 1e-3, params)
        array.append(time.perf_counter() - middle)
        fast.append(middle - start)
    return statistics.median(fast), statistics.median(array)


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
    plant, chain, bookkeeping, steps = split_per_step()
    total = plant + chain + bookkeeping
    print(
        f"  per step (mean of {steps}): plant {1e6 * plant:6.1f} us, chain {1e6 * chain:6.1f} us, "
        f"loop bookkeeping {1e6 * bookkeeping:5.1f} us"
    )
    print(f"    sum {1e6 * total:6.1f} us = real-time factor {1e-3 / total:5.1f}x of the loop")
    print(
        f"    shares: plant {100 * plant / total:4.1f} %, chain {100 * chain / total:4.1f} %, "
        f"bookkeeping {100 * bookkeeping / total:4.1f} %"
    )
    fast, array = integration_step_times()
    print(
        f"  one plant integration step (single sample): rk4_step_floats {1e6 * fast:5.1f} us "
        f"(the plant's), rk4_step {1e6 * array:5.1f} us (array API)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
