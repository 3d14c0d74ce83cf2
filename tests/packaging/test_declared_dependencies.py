"""Each package declares what its code imports: package.xml (for rosdep) and setup.py (for pip), both ways.

The imports are read from the installed code of every package under src/ (``<pkg>/<pkg>/**.py`` and
``launch/*.py``; ``setup.py`` and tools are not installed) with ast, lazy imports included, and classified:
the standard library (ignored), a package of this repository (``exec_depend`` on it), a ROS package (in the
ament index, or one of :data:`FULL_ROS_INSTALL_ONLY`: ``exec_depend`` on it), else a third-party
distribution (``importlib.metadata.packages_distributions``): its rosdep key from :data:`ROSDEP_KEYS` as an
``exec_depend``, or, where rosdistro has no key, a ``no rosdep key`` comment in package.xml and a line in
the README's install notes; and the distribution in setup.py's ``install_requires``. A declaration that no
import needs fails too, unless its line in package.xml carries a comment saying why (an executable run by
name, types loaded by name).
"""

from __future__ import annotations

import ast
import importlib.metadata
import os
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from catkin_pkg.package import parse_package

REPO = Path(__file__).resolve().parents[2]
PACKAGE_DIRS = sorted(p for p in (REPO / "src").iterdir() if (p / "package.xml").is_file())
OURS = frozenset(p.name for p in PACKAGE_DIRS)
README = REPO / "README.md"
FULL_ROS_INSTALL_ONLY = frozenset({"launch", "launch_ros"})
"""ROS packages that come with a full ROS install (apt) only, not with the PyPI wheels of this environment."""

ROSDEP_KEYS: dict[str, str | None] = {
    "numpy": "python3-numpy",
    "pyyaml": "python3-yaml",
    "scipy": "python3-scipy",
    "matplotlib": "python3-matplotlib",
    "pyserial": "python3-serial",
    "rosbags": "python3-rosbags-pip",
    "mcap-ros2-support": "mcap-ros2-support",
    "python-can": "python3-can",
    "canopen": None,
    "mcap": None,
    "zstandard": None,
    "lz4": None,
    "pyarrow": None,
    "distributed": None,
}
"""Distribution (normalised name) -> its rosdep key, None where rosdistro has none. Looked up in
ros/rosdistro ``rosdep/python.yaml`` and ``rosdep/base.yaml`` (commit 8468e88, 2026-08-22); a distribution
missing here fails the test: look it up there and add it."""

SETUP_ONLY = frozenset({"setuptools"})
"""install_requires entries of ament_python's build, not imports."""


def normalise(distribution: str) -> str:
    """PEP 503 normalised distribution name."""
    return re.sub(r"[-_.]+", "-", distribution).lower()


@dataclass
class Needs:
    """What one package's code imports, by kind; each name with the first file importing it."""

    ours: dict[str, str] = field(default_factory=dict)
    ros: dict[str, str] = field(default_factory=dict)
    third_party: dict[str, str] = field(default_factory=dict)
    unknown: dict[str, str] = field(default_factory=dict)


def installed_sources(package_dir: Path) -> list[Path]:
    """The package's Python files that are installed: its module tree and its launch files."""
    return sorted([*(package_dir / package_dir.name).rglob("*.py"), *(package_dir / "launch").glob("*.py")])


def imported_names(source: str) -> set[str]:
    """Top-level names of the absolute imports of a module (lazy ones in functions included)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


def ament_packages() -> frozenset[str]:
    """Packages registered in the ament index of this Python's prefix and of ``AMENT_PREFIX_PATH``."""
    prefixes = [sys.prefix, *filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep))]
    found: set[str] = set()
    for prefix in prefixes:
        index = Path(prefix) / "share" / "ament_index" / "resource_index" / "packages"
        if index.is_dir():
            found.update(item.name for item in index.iterdir())
    return frozenset(found)


def classify(package_dir: Path) -> Needs:
    """The package's imports sorted into ours, ROS and third-party distributions (normalised names)."""
    distributions = importlib.metadata.packages_distributions()
    ros = ament_packages() | FULL_ROS_INSTALL_ONLY
    needs = Needs()
    for path in installed_sources(package_dir):
        where = str(path.relative_to(package_dir))
        for name in sorted(imported_names(path.read_text(encoding="utf-8"))):
            if name in sys.stdlib_module_names or name == package_dir.name:
                continue
            if name in OURS:
                needs.ours.setdefault(name, where)
            elif name in ros:
                needs.ros.setdefault(name, where)
            elif name in distributions:
                needs.third_party.setdefault(normalise(distributions[name][0]), where)
            else:
                needs.unknown.setdefault(name, where)
    return needs


def install_requires(setup_py: Path) -> set[str]:
    """Normalised distribution names of ``setup(install_requires=[...])`` (string literals only)."""
    for node in ast.walk(ast.parse(setup_py.read_text(encoding="utf-8"))):
        if isinstance(node, ast.keyword) and node.arg == "install_requires":
            assert isinstance(node.value, ast.List), f"{setup_py}: install_requires is not a list literal"
            return {
                normalise(re.split(r"[<>=!~;\[ ]", item.value, maxsplit=1)[0])
                for item in node.value.elts
                if isinstance(item, ast.Constant) and isinstance(item.value, str)
            }
    return set()


def explained_depends(package_xml: Path) -> set[str]:
    """``exec_depend``s whose line carries a comment (why it is declared though nothing imports it)."""
    pattern = re.compile(r"<exec_depend>\s*([^<\s]+)\s*</exec_depend>[ \t]*<!--.+-->")
    return {m.group(1) for m in pattern.finditer(package_xml.read_text(encoding="utf-8"))}


def no_key_comment(package_xml: Path) -> str:
    """The text of package.xml's comments that mention a missing rosdep key ("" if none)."""
    comments = re.findall(r"<!--(.*?)-->", package_xml.read_text(encoding="utf-8"), flags=re.S)
    return " ".join(text for text in comments if "no rosdep key" in text.lower())


def readme_install_notes() -> str:
    """The README's section on what rosdep cannot install."""
    text = README.read_text(encoding="utf-8")
    match = re.search(r"^#+ [^\n]*rosdep[^\n]*\n(.*?)(?=^#+ |\Z)", text, flags=re.M | re.S | re.I)
    return match.group(1) if match else ""


@pytest.mark.parametrize("package_dir", PACKAGE_DIRS, ids=lambda p: p.name)
def test_every_import_is_declared_in_package_xml_and_setup_py(package_dir: Path) -> None:
    needs = classify(package_dir)
    package = parse_package(str(package_dir / "package.xml"))
    declared = {d.name for d in package.exec_depends}
    requires = install_requires(package_dir / "setup.py")
    problems = [
        f"imports {name} ({where}), which no installed distribution provides"
        for name, where in needs.unknown.items()
    ]
    for name, where in {**needs.ours, **needs.ros}.items():
        if name not in declared:
            problems.append(f"imports {name} ({where}) without <exec_depend>{name}</exec_depend>")
    comment = no_key_comment(package_dir / "package.xml")
    notes = readme_install_notes()
    for distribution, where in needs.third_party.items():
        if distribution not in ROSDEP_KEYS:
            problems.append(
                f"imports {distribution} ({where}): not in ROSDEP_KEYS; look its rosdep key up in rosdistro"
            )
            continue
        key = ROSDEP_KEYS[distribution]
        if key is not None and key not in declared:
            problems.append(f"imports {distribution} ({where}) without <exec_depend>{key}</exec_depend>")
        if key is None and not re.search(rf"\b{re.escape(distribution)}\b", comment, flags=re.I):
            problems.append(
                f"imports {distribution} ({where}), which has no rosdep key: say so in a "
                "'no rosdep key' comment of package.xml"
            )
        if key is None and not re.search(rf"`{re.escape(distribution)}`", notes, flags=re.I):
            problems.append(
                f"imports {distribution}, which has no rosdep key: list it in the README's "
                "rosdep install notes"
            )
        if distribution not in requires:
            problems.append(f"imports {distribution} ({where}) but setup.py's install_requires lacks it")
    assert not problems, f"{package.name}:\n  " + "\n  ".join(problems)


@pytest.mark.parametrize("package_dir", PACKAGE_DIRS, ids=lambda p: p.name)
def test_every_declaration_is_imported_or_explained(package_dir: Path) -> None:
    needs = classify(package_dir)
    package = parse_package(str(package_dir / "package.xml"))
    used = set(needs.ours) | set(needs.ros) | {ROSDEP_KEYS.get(d) for d in needs.third_party}
    explained = explained_depends(package_dir / "package.xml")
    unused = sorted(d.name for d in package.exec_depends if d.name not in used | explained)
    extra = sorted(install_requires(package_dir / "setup.py") - set(needs.third_party) - SETUP_ONLY)
    assert not unused, (
        f"{package.name}: <exec_depend> {unused} imported nowhere in the package: remove, or say why on its "
        "line (<!-- ... -->)"
    )
    assert not extra, f"{package.name}: setup.py's install_requires {extra} imported nowhere in the package"


def test_the_classification_sees_each_kind() -> None:
    """The checks above are not vacuous: smm_bag's imports of each kind are found."""
    needs = classify(REPO / "src" / "smm_bag")
    assert {"smm_msgs_py", "smm_node_runtime", "smm_schema"} <= set(needs.ours)
    assert {"rclpy", "std_srvs", "rcl_interfaces"} <= set(needs.ros)
    assert {"numpy", "pyyaml", "mcap", "zstandard", "lz4", "rosbags"} <= set(needs.third_party)
    assert not needs.unknown


def test_a_missing_declaration_is_found(tmp_path: Path) -> None:
    """A package importing scipy and std_msgs with neither declared fails the first check's rules."""
    package_dir = tmp_path / "smm_probe"
    (package_dir / "smm_probe").mkdir(parents=True)
    (package_dir / "smm_probe" / "__init__.py").write_text("import scipy\nfrom std_msgs.msg import Header\n")
    needs = classify(package_dir)
    assert needs.third_party == {"scipy": "smm_probe/__init__.py"}
    assert needs.ros == {"std_msgs": "smm_probe/__init__.py"}
    (package_dir / "package.xml").write_text(
        "<package><exec_depend>std_msgs</exec_depend>  <!-- why -->\n"
        "<exec_depend>rclpy</exec_depend>\n<!-- No rosdep key: lz4 --></package>"
    )
    assert explained_depends(package_dir / "package.xml") == {"std_msgs"}
    assert "lz4" in no_key_comment(package_dir / "package.xml")
    (package_dir / "setup.py").write_text("setup(install_requires=['setuptools', 'SciPy>=1.0', 'py_yaml'])")
    assert install_requires(package_dir / "setup.py") == {"setuptools", "scipy", "py-yaml"}
