"""``smm-launch`` refuses a mistyped gain and a misspelled node section before anything starts (processes
and ``--composed``), and the command lines of ``--dry-run`` run when pasted into a shell."""

from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from ros_harness import run_side_by_side
from smm_bringup.launcher import run
from smm_bringup.supervisor import EXIT_CONFIGURATION_ERROR, EXIT_OK

pytestmark = pytest.mark.ros

TIMEOUT_S = 120.0
TYPO = "/**/controller_node:\n  ros__parameters:\n    fpdeso:\n      fuzzy:\n        kd00: [1.0, 1.0]\n"
SECTION = "/smm/controler_node:\n  ros__parameters:\n    fpdeso:\n      fuzzy:\n        kd0: [1.0, 1.0]\n"


def _files(tmp_path: Path) -> tuple[Path, Path]:
    typo, section = tmp_path / "typo.yaml", tmp_path / "section.yaml"
    typo.write_text(TYPO)
    section.write_text(SECTION)
    return typo, section


def test_run_refuses_a_mistyped_gain_and_a_misspelled_section(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    typo, section = _files(tmp_path)
    for mode in ([], ["--composed"], ["--dry-run"], ["--chain", "split", "--reference", "node"]):
        assert run([*mode, "--params-file", str(typo)]) == EXIT_CONFIGURATION_ERROR
        captured = capsys.readouterr()
        assert "'fpdeso.fuzzy.kd00'" in captured.err and "did you mean 'fpdeso.fuzzy.kd0'?" in captured.err
        assert str(typo) in captured.err and "'/**/controller_node'" in captured.err
        assert "started" not in captured.out and "created" not in captured.out
        assert run([*mode, "--params-file", str(section)]) == EXIT_CONFIGURATION_ERROR
        captured = capsys.readouterr()
        assert "'/smm/controler_node'" in captured.err and "did you mean 'controller_node'?" in captured.err


def test_the_controller_reads_a_split_graphs_td_settings_only_with_the_internal_chain(tmp_path: Path) -> None:
    td = tmp_path / "td.yaml"
    td.write_text("/**/controller_node:\n  ros__parameters:\n    td:\n      speed: [100.0, 100.0]\n")
    assert run(["--dry-run", "--params-file", str(td)]) == EXIT_OK  # fused: controller_node runs the TD
    assert run(["--dry-run", "--chain", "split", "--params-file", str(td)]) == EXIT_CONFIGURATION_ERROR


@pytest.mark.parametrize("mode", ["processes", "composed"])
def test_smm_launch_exits_2_without_a_traceback_and_starts_nothing(
    ros_domain_id: int, tmp_path: Path, mode: str
) -> None:
    extra = ["--composed"] if mode == "composed" else []
    commands = [
        [sys.executable, "-m", "smm_bringup.launcher", *extra, "--params-file", str(path)]
        for path in _files(tmp_path)
    ]
    results = run_side_by_side(commands, TIMEOUT_S)
    for (code, out, err), needle in zip(
        results, ("'fpdeso.fuzzy.kd00'", "'/smm/controler_node'"), strict=True
    ):
        assert code == EXIT_CONFIGURATION_ERROR, err
        assert "Traceback" not in err and needle in err, err
        assert len(err.strip().splitlines()) == 1, err
        assert "started" not in out and "created" not in out, out


def test_dry_run_commands_run_when_pasted_into_a_shell(
    ros_processes: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["--dry-run", "--duration", "0.05", "--seed", "3"]) == EXIT_OK
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and "reference.sine.amplitude:=[1.0, 0.785]" in shlex.split(lines[1])
    for line in lines:
        check = subprocess.run(["bash", "-n", "-c", line], capture_output=True, text=True, check=False)
        assert check.returncode == 0, check.stderr
    controller = ros_processes.start("controller", ["bash", "-c", f"exec {lines[1]}"])
    simulator = ros_processes.start("simulator", ["bash", "-c", f"exec {lines[0]}"])
    # lockstep: the simulator completes its 50 steps only if the pasted controller answers every one
    assert simulator.wait(TIMEOUT_S) == 0, simulator.logs() + controller.logs()
    assert controller.alive(), controller.logs()
