"""Batched closed loop against the scalar one: scalar steps/s, batched aggregate steps/s, their ratio, and the
wall time of a 1,000-run case-2 FPDESO sweep over the machine's cores (smm-sweep's local path).

Targets (issue 24): the 1,000-run sweep in under 15 s on a 2-core machine, and at least 30x the scalar
loop's throughput in the same run. Figures only: measure on a quiet machine.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from smm_analysis.batch.loop import run_batch
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.scenarios import get_scenario
from smm_analysis.sweep.execute import default_workers, run_sweep
from smm_analysis.sweep.spec import parse_spec

RUNS = 1000
SPEC = {
    "name": "bench",
    "controller": "fpdeso",
    "scenarios": ["case2"],
    "gains": {"fpdeso.fuzzy.kd0": {"range": [80.0, 130.0]}, "fpdeso.fuzzy.kp0": {"range": [3500.0, 4500.0]}},
    "sampling": {"method": "lhs", "count": RUNS // 10, "seed": 1},
    "plant_draws": {"count": 10, "seed": 2, "parameters": {"seed": {"integers": [0, 1_000_000]}}},
    "objectives": ["RMS_alpha"],
    "batch_size": RUNS // default_workers(),
}
TARGET_S = 15.0
TARGET_RATIO = 30.0


def main() -> None:
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    scenario = get_scenario("case2")
    steps = round(scenario.duration * 1000) + 1
    start = time.perf_counter()
    run_closed_loop(scenario, "fpdeso", record_internals=False)
    scalar = steps / (time.perf_counter() - start)
    spec = parse_spec(SPEC)
    one_batch = [spec.settings(run_id) for run_id in range(spec.batch_size)]
    start = time.perf_counter()
    run_batch(one_batch)
    per_process = len(one_batch) * steps / (time.perf_counter() - start)
    workers = default_workers()
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        run_sweep(spec, Path(folder) / "out", workers=workers)
        wall = time.perf_counter() - start
    batched = spec.run_count * steps / wall
    print(f"scalar loop (case2, FPDESO, 1 run):  {scalar:12,.0f} steps/s")
    print(
        f"batched loop, one process ({len(one_batch)} runs): {per_process:12,.0f} steps/s "
        f"({per_process / scalar:.1f} x)"
    )
    print(f"batched sweep ({spec.run_count} runs, {workers} processes): {batched:12,.0f} steps/s aggregate")
    print(f"ratio batched / scalar:              {batched / scalar:12.1f} x   (target >= {TARGET_RATIO:g} x)")
    print(f"1,000-run case-2 sweep wall time:    {wall:12.1f} s   (target < {TARGET_S:g} s on 2 cores)")


if __name__ == "__main__":
    main()
