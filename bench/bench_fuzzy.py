"""Fuzzy PD inference: our engine against scikit-fuzzy's ControlSystemSimulation (run by ``make bench``).

Same rule base (Table 1, rows ce, columns e, both outputs f(k_e), f(k_de)), same membership functions,
same output grid (201 points over [-1, 1]). Antecedent universes have the triangle vertices on grid
points, so skfuzzy's interpolated input memberships are exact.

Two agreements are printed:

* Mamdani inference + centroid on the uniform output grid (SPEC section 4): skfuzzy's simulation
  provides the implication level of every consequent term (fuzzification, AND = min, accumulation =
  max), and ``skfuzzy.defuzz(universe, max_L min(level_L, mf_L), "centroid")`` gives the crisp value.
  Target: agreement to 1e-9.
* skfuzzy's own ``sim.output``: its CrispValueCalculator inserts into the universe the points where each
  term's interpolated MF crosses its level before integrating, a different discretisation of eq. 17,
  so it differs by O(grid step^2); the printout shows that difference and that it shrinks on a finer
  grid.

Timing: median time per evaluation (one (e~, ce~) pair, both outputs). skfuzzy takes tens of
milliseconds per evaluation, so it is timed on a subset and checked on as many of the 10,000 inputs as
fit in about two minutes. Nothing here asserts on time.
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from typing import Any

import numpy as np
from smm_controller.fuzzy import MamdaniSystem
from smm_controller.fuzzy_batch import MamdaniBatch, evaluate_system
from smm_controller.rules import PD_LABELS, TABLE_1, pd_gain_system, pd_output_variable

N_INPUTS = 10_000
SKFUZZY_TIMED = 200
# skfuzzy takes ~30-50 ms per evaluation, so checking all inputs takes several minutes; the budget only
# guards against a much slower machine (override with SMM_BENCH_SKFUZZY_BUDGET_S).
SKFUZZY_BUDGET_S = float(os.environ.get("SMM_BENCH_SKFUZZY_BUDGET_S", "1500"))
GRID_POINTS = 201


def build_skfuzzy(grid_points: int) -> tuple[Any, Any, Any, Any]:
    """The PD rule base as a scikit-fuzzy control system; returns (module, simulation, f_ke, f_kde)."""
    import skfuzzy
    from skfuzzy import control

    # 601 points: step 1/300, so the vertices k/3 of the triangles are grid points.
    input_universe = np.linspace(-1.0, 1.0, 601)
    output_universe = np.linspace(-1.0, 1.0, grid_points)
    error = control.Antecedent(input_universe, "e")
    rate = control.Antecedent(input_universe, "ce")
    f_ke = control.Consequent(output_universe, "f_ke", defuzzify_method="centroid")
    f_kde = control.Consequent(output_universe, "f_kde", defuzzify_method="centroid")
    sigma = pd_output_variable().mfs[0].sigma  # type: ignore[attr-defined]
    for k, label in enumerate(PD_LABELS):
        centre = -1.0 + 2.0 * k / 6.0
        for antecedent in (error, rate):
            antecedent[label] = skfuzzy.trimf(input_universe, [centre - 1 / 3, centre, centre + 1 / 3])
        for consequent in (f_ke, f_kde):
            consequent[label] = skfuzzy.gaussmf(output_universe, centre, sigma)
    rules = [
        control.Rule(
            error[e_label] & rate[ce_label], (f_ke[TABLE_1[row][col][0]], f_kde[TABLE_1[row][col][1]])
        )
        for row, ce_label in enumerate(PD_LABELS)
        for col, e_label in enumerate(PD_LABELS)
    ]
    # cache=True keeps the per-term implication levels after compute(); never flushed during a run.
    simulation = control.ControlSystemSimulation(
        control.ControlSystem(rules), cache=True, flush_after_run=100 * N_INPUTS
    )
    return skfuzzy, simulation, f_ke, f_kde


def skfuzzy_evaluate(
    skfuzzy: Any, simulation: Any, consequents: tuple[Any, Any], e: float, ce: float
) -> tuple[list[float], list[float]]:
    """Returns (uniform-grid Mamdani centroid from skfuzzy's term levels, skfuzzy's own outputs)."""
    simulation.input["e"] = e
    simulation.input["ce"] = ce
    simulation.compute()
    uniform, native = [], []
    for consequent in consequents:
        aggregated = np.zeros_like(consequent.universe)
        for term in consequent.terms.values():
            level = term.membership_value[simulation]
            if level is not None:
                aggregated = np.maximum(aggregated, np.minimum(level, term.mf))
        uniform.append(float(skfuzzy.defuzz(consequent.universe, aggregated, "centroid")))
        native.append(float(simulation.output[consequent.label]))
    return uniform, native


def time_ours(batch: MamdaniBatch, inputs: np.ndarray, block: int = 100) -> float:
    """Median over blocks of ``block`` evaluations of the time per evaluation (s)."""
    pairs = [((float(e), float(ce)),) for e, ce in inputs]
    per_block = []
    for start in range(0, len(pairs) - block + 1, block):
        chunk = pairs[start : start + block]
        begin = time.perf_counter()
        for pair in chunk:
            batch.evaluate_flat(pair)
        per_block.append((time.perf_counter() - begin) / block)
    return statistics.median(per_block)


def grid_refinement(inputs: np.ndarray) -> None:
    """Difference to skfuzzy's native output on 201 and 2001 output points (a few inputs)."""
    for points in (GRID_POINTS, 2001):
        skfuzzy, simulation, f_ke, f_kde = build_skfuzzy(points)
        ours = pd_gain_system(TABLE_1, points)
        worst = 0.0
        for e, ce in inputs:
            _, native = skfuzzy_evaluate(skfuzzy, simulation, (f_ke, f_kde), float(e), float(ce))
            crisp = evaluate_system(ours, (float(e), float(ce)))
            worst = max(worst, float(np.max(np.abs(np.subtract(crisp, native)))))
        print(
            f"  grid {points:5d} points: max |ours - skfuzzy sim.output| = {worst:.3e} ({len(inputs)} inputs)"
        )


def main() -> int:
    try:
        import skfuzzy  # noqa: F401
    except ImportError:
        print("scikit-fuzzy is not importable: install it (requirements-dev.txt) to run this benchmark")
        return 1
    rng = np.random.default_rng(2021)
    inputs = rng.uniform(-1.0, 1.0, size=(N_INPUTS, 2))
    system: MamdaniSystem = pd_gain_system(TABLE_1, GRID_POINTS)
    batch = MamdaniBatch([system])
    ours = np.array([batch.evaluate_flat(((float(e), float(ce)),)) for e, ce in inputs])

    skfuzzy_module, simulation, f_ke, f_kde = build_skfuzzy(GRID_POINTS)
    uniform_diff: list[float] = []
    native_diff: list[float] = []
    sk_times: list[float] = []
    begin = time.perf_counter()
    for k, (e, ce) in enumerate(inputs):
        start = time.perf_counter()
        uniform, native = skfuzzy_evaluate(skfuzzy_module, simulation, (f_ke, f_kde), float(e), float(ce))
        if k < SKFUZZY_TIMED:
            sk_times.append(time.perf_counter() - start)
        uniform_diff.append(float(np.max(np.abs(ours[k] - uniform))))
        native_diff.append(float(np.max(np.abs(ours[k] - native))))
        if (k + 1) % 1000 == 0:
            print(f"  skfuzzy: {k + 1} of {N_INPUTS} inputs checked", flush=True)
        if time.perf_counter() - begin > SKFUZZY_BUDGET_S:
            break
    checked = len(uniform_diff)

    ours_time = time_ours(batch, inputs)
    pair_batch = MamdaniBatch([system, pd_gain_system(TABLE_1, GRID_POINTS)])
    pairs = [((0.3, -0.2), (-0.7, 0.1)), ((0.05, 0.02), (0.01, -0.03))]
    step_times = []
    for _ in range(2000):
        start = time.perf_counter()
        pair_batch.evaluate_flat(pairs[_ % 2])
        step_times.append(time.perf_counter() - start)
    sk_median = statistics.median(sk_times)

    print(f"rule base: Table 1 (49 rules), 2 outputs, output grid {GRID_POINTS} points")
    scope = (
        "all"
        if checked == N_INPUTS
        else f"{checked} of {N_INPUTS} (skfuzzy time budget {SKFUZZY_BUDGET_S:.0f} s)"
    )
    print(f"inputs checked against skfuzzy: {scope}")
    print(
        f"max |ours - skfuzzy| (Mamdani levels from the simulation, centroid on the uniform grid): "
        f"{max(uniform_diff):.3e}  (target <= 1e-9: {'met' if max(uniform_diff) <= 1e-9 else 'NOT met'})"
    )
    print(
        f"max |ours - skfuzzy sim.output| (skfuzzy inserts the MF/level crossings into the grid): "
        f"{max(native_diff):.3e}"
    )
    grid_refinement(inputs[:20])
    print(f"median time per evaluation, ours:    {ours_time * 1e6:10.2f} us  (all {N_INPUTS} inputs)")
    print(f"median time per evaluation, skfuzzy: {sk_median * 1e6:10.2f} us  ({len(sk_times)} inputs)")
    print(f"ratio skfuzzy / ours: {sk_median / ours_time:8.0f}x  (target >= 1000x)")
    print(
        f"one control step of the schedule (2 joints x 2 outputs, one batch): "
        f"{statistics.median(step_times) * 1e6:.2f} us median"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
