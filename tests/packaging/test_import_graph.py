"""One role per package, checked on the import graph read from the source (ast), not from a list.

Rules (docs/DESIGN.md, "Packages and their roles"):
- only the compositions (``smm_bringup``, ``smm_direct_loop``) import the ROS side (node modules) of two
  node packages;
- ``smm_hw_bridge`` imports nothing of ``smm_controller`` (the bridge never knows the control law);
- ``smm_controller`` imports nothing of ``smm_sim``;
- ``smm_bag`` (bag storage and ROS I/O) imports nothing of the stack but ``smm_msgs_py``,
  ``smm_node_runtime`` and ``smm_schema``;
- ``smm_msgs_py`` defines no ``Node`` subclass and imports no node runtime (executor, parameters);
- an algorithm module (every module of an algorithm package but its node modules) reaches no ``rclpy``,
  directly or through the modules it imports.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"
BRINGUP = "smm_bringup"
COMPOSITIONS = frozenset({BRINGUP, "smm_direct_loop"})
"""Packages that compose the nodes of several node packages (the graph; the direct loop's process)."""
BRIDGE = "smm_hw_bridge"
MESSAGE_CONTRACT = "smm_msgs_py"
NODE_RUNTIME = "smm_node_runtime"
ROS_BASE_CLASSES = frozenset({"Node", "LifecycleNode"})
ROS_ROOTS = ("rclpy",)
ALGORITHM_PACKAGES = ("smm_dynamics", "smm_controller", "smm_sim", "smm_analysis", "smm_hw_bridge")
"""Packages whose modules are algorithms (pure numpy), except their node modules."""
BAG_STORAGE = "smm_bag"
SCHEMA = "smm_schema"
BAG_STORAGE_MAY_IMPORT = frozenset({MESSAGE_CONTRACT, NODE_RUNTIME, SCHEMA})
"""The only packages of the stack that the bag storage layer imports (analysis sits on top of it)."""


@dataclass
class Module:
    """One source module: what it imports and which classes it defines (with their base names)."""

    name: str
    package: str
    imports: set[str] = field(default_factory=set)
    classes: dict[str, set[str]] = field(default_factory=dict)


def _resolve(module: str, level: int, target: str | None) -> str:
    if level == 0:
        return target or ""
    base = module.split(".")[:-level] if level else module.split(".")
    return ".".join([*base, target] if target else base)


def read_module(name: str, package: str, source: str) -> Module:
    """Parse ``source`` (module ``name`` of ``package``): every import, at any depth, and every class."""
    module = Module(name, package)
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            module.imports.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(name, node.level, node.module)
            module.imports.add(base)
            module.imports.update(f"{base}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.ClassDef):
            module.classes[node.name] = {
                base.id if isinstance(base, ast.Name) else base.attr
                for base in node.bases
                if isinstance(base, (ast.Name, ast.Attribute))
            }
    return module


def read_tree(src: Path) -> dict[str, Module]:
    """Every module of every package under ``src`` (``src/<pkg>/<pkg>/**.py``), by dotted name."""
    modules: dict[str, Module] = {}
    for package_dir in sorted(p for p in src.iterdir() if (p / "package.xml").is_file()):
        package = package_dir.name
        for path in sorted((package_dir / package).rglob("*.py")):
            parts = path.relative_to(package_dir).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            modules[name] = read_module(name, package, path.read_text())
    return modules


class ImportGraph:
    """The stack's modules and the edges between them (imports of our own modules only)."""

    def __init__(self, modules: Mapping[str, Module]) -> None:
        self.modules = dict(modules)
        self.edges = {name: self._targets(module.imports) for name, module in self.modules.items()}
        self.node_classes = self._node_classes()

    def _targets(self, imports: Iterable[str]) -> set[str]:
        targets = set()
        for imported in imports:
            parts = imported.split(".")
            for end in range(len(parts), 0, -1):
                candidate = ".".join(parts[:end])
                if candidate in self.modules:
                    targets.add(candidate)
                    break
        return targets

    def _node_classes(self) -> set[str]:
        """Names of classes that derive from ``Node`` here (through our own base classes too)."""
        found = set(ROS_BASE_CLASSES)
        grown = True
        while grown:
            grown = False
            for module in self.modules.values():
                for cls, bases in module.classes.items():
                    if cls not in found and bases & found:
                        found.add(cls)
                        grown = True
        return found - ROS_BASE_CLASSES

    def defines_node(self, name: str) -> bool:
        """True when module ``name`` defines a ``Node`` subclass."""
        return any(
            bases & (self.node_classes | ROS_BASE_CLASSES) for bases in self.modules[name].classes.values()
        )

    def reachable(self, name: str) -> set[str]:
        """Modules that ``name`` imports, directly or through others (itself included)."""
        seen, todo = {name}, [name]
        while todo:
            for target in self.edges[todo.pop()] - seen:
                seen.add(target)
                todo.append(target)
        return seen

    def reaches_ros(self, name: str) -> bool:
        """True when module ``name`` imports ``rclpy``, directly or through our modules."""
        return any(
            imported.split(".")[0] in ROS_ROOTS
            for reached in self.reachable(name)
            for imported in self.modules[reached].imports
        )

    def node_packages(self) -> set[str]:
        """Packages holding at least one node class."""
        return {self.modules[name].package for name in self.modules if self.defines_node(name)}

    def node_modules(self, package: str) -> set[str]:
        """The ROS side of ``package``: its modules that define a node or reach one of its node modules."""
        own = {name for name, module in self.modules.items() if module.package == package}
        defining = {name for name in own if self.defines_node(name)}
        return {name for name in own if self.reachable(name) & defining}

    def violations(self) -> list[str]:
        """Every broken rule, one line each (empty when the layout holds)."""
        found: list[str] = []
        node_packages = self.node_packages()
        node_side = {package: self.node_modules(package) for package in node_packages}
        for package in sorted({module.package for module in self.modules.values()} - COMPOSITIONS):
            own = [name for name, module in self.modules.items() if module.package == package]
            used = {
                other
                for name in own
                for other, modules in node_side.items()
                if other != package and self.edges[name] & modules
            }
            if len(used) >= 2:
                allowed = ", ".join(sorted(COMPOSITIONS))
                found.append(f"{package} imports the nodes of {sorted(used)}: only {allowed} may")
        for name, module in sorted(self.modules.items()):
            imported_packages = {self.modules[target].package for target in self.edges[name]}
            if module.package == "smm_controller" and "smm_sim" in imported_packages:
                found.append(f"{name} imports smm_sim")
            if module.package == BRIDGE and "smm_controller" in imported_packages:
                found.append(f"{name} imports smm_controller")
            above_storage = imported_packages - BAG_STORAGE_MAY_IMPORT - {BAG_STORAGE}
            if module.package == BAG_STORAGE and above_storage:
                found.append(f"{name} imports {', '.join(sorted(above_storage))}: bag storage is below them")
            if module.package == MESSAGE_CONTRACT:
                if self.defines_node(name):
                    found.append(f"{name} defines a Node subclass")
                if NODE_RUNTIME in imported_packages or any(
                    imported.startswith(("rclpy.node", "rclpy.executors", "rclpy.parameter"))
                    for imported in module.imports
                ):
                    found.append(f"{name} imports node runtime or parameter machinery")
            if (
                module.package in ALGORITHM_PACKAGES
                and name not in node_side.get(module.package, set())
                and self.reaches_ros(name)
            ):
                found.append(f"algorithm module {name} imports rclpy")
        return found


def import_cycles(graph: ImportGraph) -> list[list[str]]:
    """Groups of two or more modules of one package that import each other, directly or in a ring.

    Every import counts: at module level, inside a function, under ``TYPE_CHECKING``; but for an import
    of the module's own enclosing package (``from pkg import submodule`` reads as one: Python initialises
    the package before the module anyway). Tarjan's strongly connected components within each package.
    """
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(name: str) -> None:
        index[name] = low[name] = len(index)
        stack.append(name)
        for target in sorted(graph.edges[name]):
            if graph.modules[target].package != graph.modules[name].package or name.startswith(f"{target}."):
                continue
            if target not in index:
                visit(target)
                low[name] = min(low[name], low[target])
            elif target in stack:
                low[name] = min(low[name], index[target])
        if low[name] == index[name]:
            component = []
            while not component or component[-1] != name:
                component.append(stack.pop())
            if len(component) > 1:
                cycles.append(sorted(component))

    for name in sorted(graph.modules):
        if name not in index:
            visit(name)
    return sorted(cycles)


# ------------------------------------------------------------------------------------------ the real tree


def test_the_stack_keeps_one_role_per_package() -> None:
    graph = ImportGraph(read_tree(SRC))
    assert graph.violations() == []


def test_the_graph_is_read_from_the_code() -> None:
    graph = ImportGraph(read_tree(SRC))
    assert {"smm_controller", "smm_sim"} <= graph.node_packages()
    assert "smm_controller.td_node" in graph.node_modules("smm_controller")
    assert "smm_controller.td" not in graph.node_modules("smm_controller")
    assert "smm_controller.td" in graph.reachable("smm_controller.td_node")
    assert graph.reaches_ros("smm_controller.td_node")
    assert not graph.reaches_ros("smm_controller.chain")
    bringup_uses = {
        graph.modules[t].package
        for name in graph.modules
        if name.startswith(BRINGUP)
        for t in graph.edges[name]
    }
    assert {"smm_controller", NODE_RUNTIME} <= bringup_uses


def test_no_two_modules_of_a_package_import_each_other() -> None:
    cycles = [cycle for cycle in import_cycles(ImportGraph(read_tree(SRC)))]
    assert not cycles, "import cycles (split the shared part into a module both import):\n" + "\n".join(
        " <-> ".join(cycle) for cycle in cycles
    )


PURE_CORES = (
    "smm_schema.fields",
    "smm_schema.ranges",
    "smm_node_runtime.health",
    "smm_node_runtime.parameter_files",
    "smm_node_runtime.stamp_gate",
    "smm_sim.config",
    "smm_sim.core",
    "smm_hw_bridge.device",
    "smm_hw_bridge.frame_device",
    "smm_hw_bridge.loop",
    "smm_hw_bridge.reading",
)
"""Logic the nodes wrap (times passed in): the node modules import it, it imports no ``rclpy``."""


@pytest.mark.parametrize("name", PURE_CORES)
def test_pure_cores_reach_no_rclpy(name: str) -> None:
    graph = ImportGraph(read_tree(SRC))
    assert name in graph.modules
    assert not graph.reaches_ros(name), f"{name} imports rclpy, directly or through our modules"


def test_the_direct_loop_composes_the_bridge_loop_and_derives_from_no_node() -> None:
    """The bridge's loop is imported by the bridge node and the direct loop's host; no node is subclassed."""
    graph = ImportGraph(read_tree(SRC))
    for user in ("smm_hw_bridge.bridge_node", "smm_direct_loop.host"):
        assert "smm_hw_bridge.loop" in graph.modules[user].imports, user
    nodes = {"HwBridgeNode", "ControllerNode"}
    derived = {
        f"{name}.{cls}": bases
        for name, module in graph.modules.items()
        if module.package == "smm_direct_loop"
        for cls, bases in module.classes.items()
    }
    assert derived and not any(bases & (nodes | graph.node_classes) for bases in derived.values()), derived


# ------------------------------------------------------------------------- each rule fires on a violation


def _tree(tmp_path: Path, files: Mapping[str, str]) -> ImportGraph:
    """A fake ``src`` tree: ``{"pkg/mod.py": source}``; every package gets a package.xml."""
    for relative, source in files.items():
        package, _, rest = relative.partition("/")
        path = tmp_path / package / package / rest
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(source)
        (tmp_path / package / "package.xml").write_text("<package/>")
    return ImportGraph(read_tree(tmp_path))


NODES = {
    "smm_controller/__init__.py": "",
    "smm_controller/td.py": "import numpy\n",
    "smm_controller/td_node.py": (
        "from rclpy.node import Node\nfrom smm_controller.td import x\nclass TdNode(Node): ...\n"
    ),
    "smm_sim/__init__.py": "",
    "smm_sim/plant.py": "import numpy\n",
    "smm_sim/sim_node.py": "from smm_node_runtime import SmmNode\nclass SimNode(SmmNode): ...\n",
    "smm_node_runtime/__init__.py": "from smm_node_runtime.node import SmmNode\n",
    "smm_node_runtime/node.py": "from rclpy.node import Node\nclass SmmNode(Node): ...\n",
    "smm_msgs_py/__init__.py": "",
    "smm_msgs_py/conversions.py": "from sensor_msgs.msg import JointState\n",
}


def test_a_clean_fake_tree_has_no_violation(tmp_path: Path) -> None:
    assert _tree(tmp_path, NODES).violations() == []


def test_a_package_starting_two_node_packages_is_refused(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_analysis/__init__.py"] = ""
    files["smm_analysis/launch.py"] = (
        "from smm_controller.td_node import TdNode\nfrom smm_sim.sim_node import SimNode\n"
    )
    assert any("smm_analysis imports the nodes of" in v for v in _tree(tmp_path, files).violations())


def test_bringup_may_import_every_node_package(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_bringup/__init__.py"] = ""
    files["smm_bringup/graph.py"] = "import smm_controller.td_node\nimport smm_sim.sim_node\n"
    assert _tree(tmp_path, files).violations() == []


def test_the_direct_loop_may_compose_the_bridge_and_the_controller(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_direct_loop/__init__.py"] = ""
    files["smm_direct_loop/host.py"] = "import smm_controller.td_node\nimport smm_sim.sim_node\n"
    assert _tree(tmp_path, files).violations() == []


def test_the_bridge_importing_the_controller_is_refused(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_hw_bridge/__init__.py"] = ""
    files["smm_hw_bridge/core.py"] = "from smm_controller.td import x\n"
    assert "smm_hw_bridge.core imports smm_controller" in _tree(tmp_path, files).violations()


def test_pure_algorithms_of_two_node_packages_are_libraries(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_analysis/__init__.py"] = ""
    files["smm_analysis/loop.py"] = "from smm_controller.td import x\nfrom smm_sim.plant import y\n"
    assert _tree(tmp_path, files).violations() == []


def test_the_controller_importing_the_simulator_is_refused(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_controller/chain.py"] = "def f():\n    from smm_sim.plant import y\n"
    assert "smm_controller.chain imports smm_sim" in _tree(tmp_path, files).violations()


def test_bag_storage_importing_the_analysis_is_refused(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_bag/__init__.py"] = ""
    files["smm_bag/recorder_node.py"] = (
        "from smm_msgs_py.conversions import x\nfrom smm_node_runtime import SmmNode\n"
        "class RecorderNode(SmmNode): ...\n"
    )
    assert _tree(tmp_path, files).violations() == []
    files["smm_bag/plots.py"] = "def f():\n    from smm_analysis.scenarios import g\n    import smm_sim\n"
    files["smm_analysis/__init__.py"] = ""
    files["smm_analysis/scenarios.py"] = "import numpy\n"
    assert _tree(tmp_path, files).violations() == [
        "smm_bag.plots imports smm_analysis, smm_sim: bag storage is below them"
    ]


def test_pure_modules_import_without_rclpy() -> None:
    """At run time too: ``smm_node_runtime`` loads its names lazily, so its pure modules pull in no rclpy."""
    modules = (*PURE_CORES, "smm_analysis.runs.rerun", "smm_analysis.runs.commands")
    code = (
        f"import sys\nfor m in {modules!r}: __import__(m)\n"
        "print(sorted(k for k in sys.modules if k.startswith('rclpy')))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]", result.stdout


def test_a_node_in_the_message_contract_is_refused(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_msgs_py/helper.py"] = "import rclpy.node\nclass Helper(rclpy.node.Node): ...\n"
    violations = _tree(tmp_path, files).violations()
    assert "smm_msgs_py.helper defines a Node subclass" in violations
    assert "smm_msgs_py.helper imports node runtime or parameter machinery" in violations


def test_parameter_machinery_in_the_message_contract_is_refused(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_node_runtime/parameters.py"] = "class ConfigParameters: ...\n"
    files["smm_msgs_py/qos.py"] = "from smm_node_runtime.parameters import ConfigParameters\n"
    assert (
        "smm_msgs_py.qos imports node runtime or parameter machinery" in _tree(tmp_path, files).violations()
    )


def test_an_algorithm_reaching_rclpy_is_refused(tmp_path: Path) -> None:
    files = dict(NODES)
    files["smm_controller/helpers.py"] = "import rclpy\n"
    files["smm_controller/fleso.py"] = "from .helpers import spin\n"
    violations = _tree(tmp_path, files).violations()
    assert "algorithm module smm_controller.helpers imports rclpy" in violations
    assert "algorithm module smm_controller.fleso imports rclpy" in violations


def test_an_import_cycle_is_found_even_inside_a_function(tmp_path: Path) -> None:
    files = {
        "smm_sim/__init__.py": "",
        "smm_sim/a.py": "from smm_sim.b import x\n",
        "smm_sim/b.py": "def f():\n    from smm_sim.c import y\n",
        "smm_sim/c.py": "import typing\nif typing.TYPE_CHECKING:\n    from smm_sim.a import z\n",
        "smm_sim/d.py": "from smm_sim.a import w\n",
        "smm_dynamics/e.py": "from smm_sim.d import v\n",
        "smm_sim/sub/__init__.py": "from smm_sim.sub.f import u\n",
        "smm_sim/sub/f.py": "from smm_sim.sub import g\n",
        "smm_sim/sub/g.py": "",
    }
    assert import_cycles(_tree(tmp_path, files)) == [["smm_sim.a", "smm_sim.b", "smm_sim.c"]]


@pytest.mark.parametrize(
    ("module", "level", "target", "expected"),
    [("a.b.c", 1, "d", "a.b.d"), ("a.b.c", 2, None, "a"), ("a.b", 0, "x.y", "x.y")],
)
def test_relative_imports_resolve_against_the_module(
    module: str, level: int, target: str | None, expected: str
) -> None:
    assert _resolve(module, level, target) == expected


# ------------------------------------------------------------------------------ the diagram in DESIGN.md


def package_dependencies(graph: ImportGraph) -> dict[str, set[str]]:
    """``{package: packages it imports}`` over the stack's own packages."""
    dependencies: dict[str, set[str]] = {module.package: set() for module in graph.modules.values()}
    for name, module in graph.modules.items():
        dependencies[module.package] |= {graph.modules[t].package for t in graph.edges[name]} - {
            module.package
        }
    return dependencies


def diagram_lines(dependencies: Mapping[str, set[str]]) -> list[str]:
    """One line per package: ``pkg -> dep, dep`` (``pkg`` alone when it imports none of ours)."""
    return [
        f"{package} -> {', '.join(sorted(used))}" if used else package
        for package, used in sorted(dependencies.items())
    ]


def test_design_md_draws_the_dependencies_the_code_has() -> None:
    text = (SRC.parent / "docs" / "DESIGN.md").read_text()
    block = text.split("<!-- package-dependencies -->")[1].split("```")[1].strip().splitlines()
    assert block == diagram_lines(package_dependencies(ImportGraph(read_tree(SRC))))


if __name__ == "__main__":
    print("\n".join(diagram_lines(package_dependencies(ImportGraph(read_tree(SRC))))))
