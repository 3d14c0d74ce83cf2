"""The commands users type are on PATH of the activated venv; node executables stay in ``lib/<pkg>/`` only."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "bags" / "sample_case2_fpdeso"
USER_COMMANDS = {
    "smm-bag": "smm_bag",
    "smm-reproduce": "smm_analysis",
    "smm-launch": "smm_bringup",
    "smm-demo": "smm_bringup",
    "smm-commission": "smm_commissioning",
}
NODE_EXECUTABLES = {
    "recorder_node": "smm_bag",
    "td_node": "smm_controller",
    "controller_node": "smm_controller",
    "smm_sim_node": "smm_sim",
    "hw_bridge_node": "smm_hw_bridge",
}

sys.path.insert(0, str(REPO / "src"))
from user_commands import link_into_bin  # noqa: E402


def activated(prefix: Path) -> dict[str, str]:
    """The environment ``. <prefix>/bin/activate`` gives: its bin first on PATH."""
    env = {k: v for k, v in os.environ.items() if k not in {"PYTHONHOME", "PYTHONPATH"}}
    env["VIRTUAL_ENV"] = str(prefix)
    env["PATH"] = os.pathsep.join([str(prefix / "bin"), "/usr/bin", "/bin"])
    return env


def run(command: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        command, capture_output=True, text=True, env=env, cwd=REPO, timeout=120, check=False
    )


VENV = Path(sys.prefix)


@pytest.mark.parametrize("name", sorted(USER_COMMANDS))
def test_user_command_is_on_path_of_the_activated_venv(name: str) -> None:
    env = activated(VENV)
    assert shutil.which(name, path=env["PATH"]) == str(VENV / "bin" / name)
    assert (VENV / "lib" / USER_COMMANDS[name] / name).is_file(), "the ros2 run layout is kept too"
    result = run([name, "--help"], env)
    assert result.returncode == 0, result.stderr
    assert f"usage: {name}" in result.stdout


def test_smm_bag_info_runs_by_name() -> None:
    result = run(["smm-bag", "info", str(SAMPLE.relative_to(REPO))], activated(VENV))
    assert result.returncode == 0, result.stderr
    assert "sample_case2_fpdeso_0.mcap" in result.stdout


@pytest.mark.parametrize("name", sorted(NODE_EXECUTABLES))
def test_node_executables_stay_in_lib_pkg(name: str) -> None:
    assert (VENV / "lib" / NODE_EXECUTABLES[name] / name).is_file()
    assert not (VENV / "bin" / name).exists()


@pytest.mark.slow
def test_pip_install_e_into_a_fresh_venv_puts_the_command_in_bin(tmp_path: Path) -> None:
    fresh = tmp_path / "venv"
    subprocess.run([sys._base_executable, "-m", "venv", "--without-pip", str(fresh)], check=True)
    site = Path(sysconfig.get_path("purelib", vars={"base": str(fresh), "platbase": str(fresh)}))
    (site / "outer.pth").write_text(sysconfig.get_path("purelib") + "\n")  # pip, setuptools, dependencies
    python = fresh / "bin" / "python"
    # A copy: `pip install -e` rewrites the package's egg-info, which the suite's own smm_bag commands read
    # as they start (on the other xdist worker too).
    source = tmp_path / "src"
    unbuilt = shutil.ignore_patterns("*.egg-info", "__pycache__")
    shutil.copytree(REPO / "src" / "smm_bag", source / "smm_bag", ignore=unbuilt)
    shutil.copy2(REPO / "src" / "user_commands.py", source)
    install = run(
        [
            str(python),
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "-e",
            str(source / "smm_bag"),
        ],
        activated(fresh),
    )
    assert install.returncode == 0, install.stderr
    assert (fresh / "lib" / "smm_bag" / "smm-bag").is_file()
    assert (fresh / "lib" / "smm_bag" / "recorder_node").is_file()
    assert (fresh / "bin" / "smm-bag").resolve() == (fresh / "lib" / "smm_bag" / "smm-bag").resolve()
    assert not (fresh / "bin" / "recorder_node").exists()
    result = run(["smm-bag", "info", str(SAMPLE)], activated(fresh))
    assert result.returncode == 0, result.stderr


def test_links_only_from_a_lib_pkg_directory(tmp_path: Path) -> None:
    scripts = tmp_path / "lib" / "pkg"
    scripts.mkdir(parents=True)
    (scripts / "tool").write_text("#!/bin/sh\n")
    assert link_into_bin(str(scripts), ["tool"]) == [str(tmp_path / "bin" / "tool")]
    assert os.readlink(tmp_path / "bin" / "tool") == "../lib/pkg/tool"
    assert link_into_bin(str(scripts), ["tool"]) == [str(tmp_path / "bin" / "tool")]  # again: replaced
    assert link_into_bin(str(tmp_path / "bin"), ["tool"]) == []  # scripts already in bin: nothing to do
