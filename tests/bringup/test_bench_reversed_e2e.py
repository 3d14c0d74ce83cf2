"""Issue 44: the reversed bench (docs/BENCH.md) with the bridge's defaults ends non-zero, nothing moved.

Lockstep ``smm-launch --plant hardware --bench-file bench_reversed.yaml``: the bridge reads joint alpha at
5.99 rad (the bench's encoder zero) and stops at once with a reason naming the parameters to check; the run
ends there (exit 3), not at the emulator's start timeout.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from launcher_run import smm_launch

pytestmark = [pytest.mark.ros, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "src" / "smm_bench_emulator" / "config" / "bench_reversed.yaml"


def test_the_reversed_bench_with_the_bridge_defaults_is_a_safety_stop(ros_processes: Any) -> None:
    code, logs = smm_launch(
        ros_processes,
        "smm-launch-reversed-defaults",
        *("--plant", "hardware", "--clock-mode", "lockstep", "--scenario", "case1", "--duration", "4"),
        *("--bench-file", str(BENCH)),
        timeout=180,
    )
    assert code == 3, logs
    assert "hw_bridge_node: the run did not control: safety stop: joint alpha reads 5.992 rad" in logs, logs
    assert logs.count("host fault (safety stop:") == 1, logs  # one fault, one error transition
    # the bridge ends the run at its stop: the graph does not wait for the emulator's start timeout
    assert "autostart: the run ends at its safety stop" in logs, logs
    assert "within its start timeout" not in logs, logs
