"""``colcon build`` of src/ gives the layout that ``ros2 run <pkg> <executable>`` runs on Jazzy."""

from __future__ import annotations

import configparser
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SRC = REPO / "src"
PACKAGES = sorted(p.name for p in SRC.iterdir() if (p / "package.xml").is_file())
COLCON = Path(sys.executable).with_name("colcon")

pytestmark = pytest.mark.xdist_group("colcon")  # one worker: one colcon build (fixture colcon_install)


def declared_console_scripts(package: str) -> list[str]:
    """Console scripts of ``package`` as setuptools reads them from its setup.py."""
    out = subprocess.run(
        [sys.executable, "-c", _PRINT_ENTRY_POINTS],
        cwd=SRC / package,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return [line for line in out.splitlines() if line]


_PRINT_ENTRY_POINTS = """
import runpy, setuptools
captured = {}
setuptools.setup = lambda **kw: captured.update(kw)
runpy.run_path("setup.py", run_name="__main__")
for spec in captured.get("entry_points", {}).get("console_scripts", []):
    print(spec.split("=")[0].strip())
"""


@pytest.fixture(scope="module")
def colcon_install(tmp_path_factory: pytest.TempPathFactory) -> Path:
    workdir = tmp_path_factory.mktemp("colcon")
    result = subprocess.run(
        [
            str(COLCON),
            "--log-base",
            str(workdir / "log"),
            "build",
            "--base-paths",
            str(SRC),
            "--build-base",
            str(workdir / "build"),
            "--install-base",
            str(workdir / "install"),
        ],
        cwd=workdir,
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    return workdir / "install"


def test_every_package_is_built(colcon_install: Path) -> None:
    assert {
        "smm_bag",
        "smm_bringup",
        "smm_controller",
        "smm_direct_loop",
        "smm_hw_bridge",
        "smm_msgs_py",
        "smm_node_runtime",
        "smm_sim",
    } <= set(PACKAGES)
    for package in PACKAGES:
        share = colcon_install / package / "share"
        assert (share / package / "package.xml").is_file()
        assert (share / "ament_index" / "resource_index" / "packages" / package).is_file()


@pytest.mark.parametrize("package", PACKAGES)
def test_executables_are_where_ros2_run_looks(colcon_install: Path, package: str) -> None:
    lib_dir = colcon_install / package / "lib" / package
    for executable in declared_console_scripts(package):
        path = lib_dir / executable
        assert path.is_file(), f"{path} missing: ros2 run {package} {executable} would fail"
        assert os.access(path, os.X_OK)


@pytest.mark.parametrize("package", PACKAGES)
def test_setup_cfg_installs_scripts_into_lib_pkg(package: str) -> None:
    config = configparser.ConfigParser()
    config.read(SRC / package / "setup.cfg")
    assert config["develop"]["script_dir"] == f"$base/lib/{package}"
    assert config["install"]["install_scripts"] == f"$base/lib/{package}"
    assert (SRC / package / "resource" / package).is_file()


def test_smm_launch_is_installed_by_smm_bringup_alone(colcon_install: Path) -> None:
    owners = sorted(p.relative_to(colcon_install).parts[0] for p in colcon_install.glob("*/lib/*/smm-launch"))
    assert owners == ["smm_bringup"]
    assert (colcon_install / "smm_bringup" / "share" / "smm_bringup" / "launch" / "smm.launch.py").is_file()


@pytest.mark.parametrize(
    ("package", "command"),
    [("smm_bag", "smm-bag"), ("smm_analysis", "smm-reproduce"), ("smm_bringup", "smm-launch")],
)
def test_user_commands_are_also_in_the_packages_bin(colcon_install: Path, package: str, command: str) -> None:
    """``install/<pkg>/bin`` is on PATH once ``install/setup.bash`` is sourced; node executables are not."""
    link = colcon_install / package / "bin" / command
    assert link.resolve() == (colcon_install / package / "lib" / package / command).resolve()
    assert not (colcon_install / "smm_bag" / "bin" / "recorder_node").exists()
    assert not (colcon_install / "smm_controller" / "bin").exists()


def test_an_installed_executable_starts_from_the_install_tree(colcon_install: Path) -> None:
    executable = colcon_install / "smm_analysis" / "lib" / "smm_analysis" / "smm-reproduce"
    site_dirs = sorted(str(p) for p in colcon_install.glob("*/lib/python3*/site-packages"))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(site_dirs), PYTHONNOUSERSITE="1")
    result = subprocess.run([str(executable), "--help"], capture_output=True, text=True, env=env, check=False)
    assert result.returncode == 0, result.stderr
    assert "usage:" in result.stdout
    where = subprocess.run(
        [sys.executable, "-c", "import smm_analysis; print(smm_analysis.__file__)"],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    ).stdout
    assert where.startswith(str(colcon_install)), where


def test_colcon_is_available() -> None:
    assert COLCON.is_file() or shutil.which("colcon"), "colcon-common-extensions is not installed"
