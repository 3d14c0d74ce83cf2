"""package.xml files are format 3 and declare dependencies that really exist."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from catkin_pkg.package import parse_package

REPO = Path(__file__).resolve().parents[2]
PACKAGE_DIRS = sorted(p for p in (REPO / "src").iterdir() if (p / "package.xml").is_file())
OURS = {p.name for p in PACKAGE_DIRS}
# Needed only by launch/*.launch.py; they come with a full ROS install (apt), not with the PyPI wheels.
FULL_ROS_INSTALL_ONLY = {"launch", "launch_ros"}
# rosdep keys that are not Python modules of the same name
ROSDEP_TO_MODULE = {
    "python3-numpy": "numpy",
    "python3-matplotlib": "matplotlib",
    "python3-pytest": "pytest",
    "python3-yaml": "yaml",
    "python3-scipy": "scipy",
    "python3-serial": "serial",
    "python3-rosbags-pip": "rosbags",
    "python3-can": "can",
    "python3-msgpack": "msgpack",
}


@pytest.mark.parametrize("package_dir", PACKAGE_DIRS, ids=lambda p: p.name)
def test_package_xml_is_format_3_with_importable_exec_depends(package_dir: Path) -> None:
    package = parse_package(str(package_dir / "package.xml"))
    assert package.package_format == 3
    assert package.name == package_dir.name
    assert package.get_build_type() == "ament_python"
    for dependency in package.exec_depends:
        if dependency.name in FULL_ROS_INSTALL_ONLY:
            continue
        module = ROSDEP_TO_MODULE.get(dependency.name, dependency.name)
        assert importlib.util.find_spec(module) is not None, f"{package.name}: exec_depend {dependency.name}"
    assert package.name not in {d.name for d in package.exec_depends}


def test_internal_dependencies_are_declared() -> None:
    for package_dir in PACKAGE_DIRS:
        package = parse_package(str(package_dir / "package.xml"))
        declared = {d.name for d in package.exec_depends}
        imported = {
            name
            for name in OURS - {package.name}
            for source in (package_dir / package.name).rglob("*.py")
            if f"from {name}" in source.read_text() or f"import {name}" in source.read_text()
        }
        assert imported <= declared, (
            f"{package.name} imports {sorted(imported - declared)} without exec_depend"
        )
