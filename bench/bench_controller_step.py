"""One full control step (ControlChain.step: TD + FLESO + fuzzy schedule + FPDESO law, both joints).

Run by ``make bench``. Inputs are recorded from a closed loop on the case1 sinusoid (RK4 plant), so the
fuzzy systems see realistic firing patterns. Prints the median time per step of the array API
(``step``) and of the float API the offline simulator uses (``step_floats``), as a share of the 1 ms
control period (target < 10 %), the time of each stage, of the baselines' chains, and of one plant
RK4 step (the float fast path the simulated plant uses, and the array API), with the real-time factor
of an offline run (chain + plant per step). Nothing asserts on time.
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable

import numpy as np
from smm_controller.chain import ControlChain, make_chain
from smm_controller.laws import PAPER_LAWS
from smm_controller.reference import SineReference

from smm_dynamics import SMMParameters, rk4_step, rk4_step_floats

DT = 0.001
STEPS = 3000


def record_inputs(name: str, params: SMMParameters) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(y, tau_applied, reference) of every step of a closed-loop case1 run."""
    chain = make_chain(name, params)
    references = SineReference().sample(np.arange(STEPS) * DT)
    q, qd, tau = np.zeros(2), np.zeros(2), np.zeros(2)
    inputs = []
    for k in range(STEPS):
        inputs.append((q.copy(), tau.copy(), references[k]))
        tau = chain.step(q, tau, references[k], DT)
        q, qd = rk4_step(q, qd, tau, DT, params)
    return inputs


def median_per_call(calls: list[Callable[[], object]], repeats: int = 3) -> float:
    """Median over calls (each timed alone, best of ``repeats`` passes) in seconds."""
    best = [float("inf")] * len(calls)
    for _ in range(repeats):
        for k, call in enumerate(calls):
            start = time.perf_counter()
            call()
            best[k] = min(best[k], time.perf_counter() - start)
    return statistics.median(best)


def time_chain(
    chain: ControlChain, inputs: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
) -> tuple[float, float]:
    """Median time per step of the array API and of the float API, replaying ``inputs`` in order."""
    chain.reset()
    array_times = []
    for y, tau, reference in inputs:
        start = time.perf_counter()
        chain.step(y, tau, reference, DT)
        array_times.append(time.perf_counter() - start)
    chain.reset()
    float_inputs = [
        ((float(y[0]), float(y[1])), (float(tau[0]), float(tau[1])), reference.tolist())
        for y, tau, reference in inputs
    ]
    float_times = []
    for measured, applied, nested in float_inputs:
        start = time.perf_counter()
        chain.step_floats(measured, applied, nested, DT)
        float_times.append(time.perf_counter() - start)
    return statistics.median(array_times), statistics.median(float_times)


def time_stages(
    chain: ControlChain, inputs: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
) -> dict[str, float]:
    """Median time of each stage of the FPDESO chain on the recorded inputs."""
    chain.reset()
    td, fleso, controller = chain.td, chain.fleso, chain.controller
    assert fleso is not None
    times: dict[str, list[float]] = {"TD": [], "FLESO": [], "FPDESO law (incl. schedule)": [], "schedule": []}
    for y, tau, reference in inputs:
        y0, y1 = y.tolist()
        start = time.perf_counter()
        q0, q1, qd0, qd1 = td.step_floats(y0, y1, DT)
        times["TD"].append(time.perf_counter() - start)
        start = time.perf_counter()
        xi = fleso.step_floats(q0, q1, float(tau[0]), float(tau[1]), DT)
        times["FLESO"].append(time.perf_counter() - start)
        ref = reference.tolist()
        start = time.perf_counter()
        controller.step_floats(ref, (q0, q1), (qd0, qd1), xi, DT)
        times["FPDESO law (incl. schedule)"].append(time.perf_counter() - start)
        schedule = controller.schedule  # type: ignore[attr-defined]
        start = time.perf_counter()
        schedule.step_floats(ref[0][0] - q0, ref[0][1] - q1, ref[1][0] - qd0, ref[1][1] - qd1)
        times["schedule"].append(time.perf_counter() - start)
    return {name: statistics.median(values) for name, values in times.items()}


def call_overhead() -> float:
    """Median time of a trivial numpy call: the machine's per-call overhead, for scale."""
    a = np.zeros(2)
    return median_per_call([lambda: np.add(a, a)] * 2000)


def main() -> int:
    params = SMMParameters()
    print(f"numpy call overhead on this machine (np.add on 2 elements): {call_overhead() * 1e6:.2f} us")
    inputs = record_inputs("fpdeso", params)
    fpdeso = make_chain("fpdeso", params)
    array_median, float_median = time_chain(fpdeso, inputs)
    period_share = float_median / DT
    print(
        f"FPDESO ControlChain.step (arrays):        {array_median * 1e6:7.2f} us"
        f" = {array_median / DT:6.2%} of 1 ms"
    )
    print(
        f"FPDESO ControlChain.step_floats (floats): {float_median * 1e6:7.2f} us"
        f" = {period_share:6.2%} of 1 ms  (target < 10 %: {'met' if period_share < 0.1 else 'NOT met'})"
    )
    for stage, seconds in time_stages(fpdeso, inputs).items():
        print(f"  {stage:28s} {seconds * 1e6:7.2f} us")
    for name in PAPER_LAWS[1:]:
        chain_array, chain_float = time_chain(make_chain(name, params), record_inputs(name, params))
        print(
            f"{name.upper():6s} chain: step {chain_array * 1e6:7.2f} us,"
            f" step_floats {chain_float * 1e6:7.2f} us"
        )
    q, qd, tau = np.array([0.3, 0.2]), np.array([0.5, -0.4]), np.array([0.1, 0.2])
    array_plant = median_per_call([lambda: rk4_step(q, qd, tau, DT, params)] * 2000)
    state, torque = (0.3, 0.2, 0.5, -0.4), (0.1, 0.2)
    plant = median_per_call([lambda: rk4_step_floats(state, torque, DT, params)] * 2000)
    per_step = float_median + plant
    print(f"plant rk4_step_floats (the simulated plant's, one sub-step): {plant * 1e6:7.2f} us")
    print(f"plant rk4_step (array API, one sub-step):                    {array_plant * 1e6:7.2f} us")
    print(
        f"offline closed loop, chain + one plant step: {per_step * 1e6:.2f} us per 1 ms step "
        f"= {DT / per_step:.1f}x real time (target >= 20x; case2 5000 steps ~ {5000 * per_step:.2f} s)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
