"""``smm-launch`` as a process of the ``ros_processes`` fixture, to its end: exit code and logs; its bag's
figures (``smm-bag analyze``)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest


def smm_launch(ros_processes: Any, name: str, *options: str, timeout: float = 600.0) -> tuple[int, str]:
    """Runs ``smm-launch options`` to its end (fails the test past ``timeout`` s): its exit code and logs."""
    launcher = ros_processes.start(name, [sys.executable, "-m", "smm_bringup.launcher", *options])
    try:
        code = launcher.popen.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"smm-launch did not finish\n{launcher.logs()}")
    logs: str = launcher.logs()
    return code, logs


def analyze(bag: Path) -> dict[str, Any]:
    """``smm-bag analyze --json --quiet bag``: its figures (asserts it exits 0)."""
    analysed = subprocess.run(
        [sys.executable, "-m", "smm_bag.cli", "analyze", "--json", "--quiet", str(bag)],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert analysed.returncode == 0, analysed.stdout + analysed.stderr
    figures: dict[str, Any] = json.loads(analysed.stdout)
    return figures
