"""What the code may not say: the laws are listed once, private names stay in their package, the schema is
below the stack, and every numeric field of every config declares its range.

- A literal tuple, list or set naming two or more of the paper's laws exists only in the table
  (``smm_controller/laws.py``); everyone else reads ``law_table()``, ``law_names()`` or ``PAPER_LAWS``. A
  dict literal keyed by two or more laws is refused in the packages too, but for the files that hold the
  paper's own per-law content (published figures, derivations, one study's two runs), listed below.
- No module imports a private module or a private name (leading underscore) of another package.
- ``smm_schema`` imports nothing of the stack's other packages (parsed, not run).
- Every config dataclass of the stack (a dataclass named ``*Config``, one declaring a range on any field, and
  every dataclass such a config holds) declares a range on each numeric field (imported and walked).
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import typing
from collections.abc import Iterator
from pathlib import Path

import pytest
from smm_controller.laws import PAPER_LAWS
from smm_schema.ranges import field_range, numeric_hint

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("src", "tests", "bench", "tools")
TABLE = ROOT / "src" / "smm_controller" / "smm_controller" / "laws.py"
_REPRODUCTION = "src/smm_analysis/smm_analysis/reproduction"
PER_LAW_CONTENT = {
    f"{_REPRODUCTION}/paper_values.py": "the paper's published figures, per law",
    f"{_REPRODUCTION}/linearisation.py": "the baselines' linear loops, per law",
    f"{_REPRODUCTION}/energy_study.py": "the study's FPDESO run against its FPD run",
}
"""Package files whose dict literals are keyed by the paper's laws, and why."""


def python_files() -> Iterator[Path]:
    for base in SOURCES:
        for path in sorted((ROOT / base).rglob("*.py")):
            if path.name != "_generated.py" and ".venv" not in path.parts:
                yield path


def law_names_in(values: list[ast.expr | None]) -> set[str]:
    return {v.value for v in values if isinstance(v, ast.Constant) and v.value in PAPER_LAWS}


def literal_law_lists(source: str, relative: str) -> list[str]:
    """Where the file ``relative`` (its text ``source``) lists two or more laws in a literal (line: names)."""
    found = []
    for node in ast.walk(ast.parse(source, relative)):
        names: set[str] = set()
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            names = law_names_in(list(node.elts))
        elif isinstance(node, ast.Dict) and relative.startswith("src/") and relative not in PER_LAW_CONTENT:
            names = law_names_in(node.keys)
        if len(names) >= 2:
            found.append(f"{relative}:{node.lineno}: {sorted(names)}")
    return found


def package_of(relative: str) -> str | None:
    """The top-level package a file of ``src/`` belongs to (None outside ``src/``)."""
    parts = relative.split("/")
    return parts[1] if parts[0] == "src" and len(parts) > 2 else None


def private_imports(source: str, relative: str) -> list[str]:
    """Imports in the file ``relative`` of another package's private module or name (line: what)."""
    own = package_of(relative)
    found = []
    for node in ast.walk(ast.parse(source, relative)):
        modules: list[tuple[str, list[str]]] = []
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            modules = [(node.module, [alias.name for alias in node.names])]
        elif isinstance(node, ast.Import):
            modules = [(alias.name, []) for alias in node.names]
        for module, names in modules:
            top = module.split(".")[0]
            if not top.startswith("smm_") or top == own:
                continue
            private = [part for part in module.split(".") if part.startswith("_")]
            private += [name for name in names if name.startswith("_")]
            if private:
                found.append(f"{relative}:{node.lineno}: {module} {private}")
    return found


def relative(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def test_only_the_table_lists_the_laws() -> None:
    found = [
        where
        for path in python_files()
        if path != TABLE
        for where in literal_law_lists(path.read_text(), relative(path))
    ]
    assert not found, "laws listed outside smm_controller/laws.py (read law_table()):\n" + "\n".join(found)


def test_no_private_name_is_imported_across_packages() -> None:
    found = [
        where
        for path in python_files()
        if package_of(relative(path))
        for where in private_imports(path.read_text(), relative(path))
    ]
    assert not found, "private names imported across packages:\n" + "\n".join(found)


@pytest.mark.parametrize(
    ("source", "refused"),
    [
        ('CHOICES = ("fpdeso", "pid")\n', True),
        ('for name in ["npd", "fpd", "x"]:\n    pass\n', True),
        ('ONE = ("fpdeso",)\nTWO = ("fpdeso", "fpdeso_retuned")\n', False),
    ],
)
def test_the_law_list_check_refuses_what_it_should(source: str, refused: bool) -> None:
    assert bool(literal_law_lists(source, "tests/probe.py")) is refused
    keyed = 'GAINS = {"pid": 1, "npd": 2}\n'
    assert literal_law_lists(keyed, "src/smm_x/smm_x/probe.py")
    assert not literal_law_lists(keyed, "src/smm_analysis/smm_analysis/reproduction/paper_values.py")


def test_the_private_import_check_refuses_what_it_should() -> None:
    source = (
        "from smm_dynamics._generated import x\nfrom smm_dynamics.model import _y\nimport smm_sim._z\n"
        "from smm_analysis._own import w\nfrom smm_dynamics.spin_form import v\n"
    )
    found = private_imports(source, "src/smm_analysis/smm_analysis/probe.py")
    assert [line.split(":")[1] for line in found] == ["1", "2", "3"]


# ----------------------------------------------------------------------------- the schema is the ground floor

SCHEMA = "smm_schema"


def stack_imports(source: str, relative: str) -> list[str]:
    """Imports in the file ``relative`` of a stack package other than its own (line: module)."""
    own = package_of(relative)
    found = []
    for node in ast.walk(ast.parse(source, relative)):
        modules: list[str] = []
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            modules = [node.module]
        elif isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        found += [
            f"{relative}:{node.lineno}: {module}"
            for module in modules
            if module.split(".")[0].startswith("smm_") and module.split(".")[0] != own
        ]
    return found


def test_the_schema_imports_nothing_of_the_stack() -> None:
    files = sorted((ROOT / "src" / SCHEMA).rglob("*.py"))
    assert any(path.name == "ranges.py" for path in files)
    found = [where for path in files for where in stack_imports(path.read_text(), relative(path))]
    assert not found, "smm_schema imports the stack it is below:\n" + "\n".join(found)


def test_the_schema_import_check_refuses_what_it_should() -> None:
    source = (
        "import smm_dynamics\nfrom smm_node_runtime.parameters import x\nfrom smm_schema.fields import y\n"
    )
    found = stack_imports(source, "src/smm_schema/smm_schema/probe.py")
    assert [line.split(":")[1] for line in found] == ["1", "2"]


# --------------------------------------------------------------------- every numeric config field has a range


def stack_modules() -> Iterator[str]:
    """Dotted names of every module of every package under ``src`` (node modules included)."""
    for package_dir in sorted(p for p in (ROOT / "src").iterdir() if (p / "package.xml").is_file()):
        for path in sorted((package_dir / package_dir.name).rglob("*.py")):
            if path.name == "_generated.py":
                continue
            parts = path.relative_to(package_dir).with_suffix("").parts
            yield ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def is_config(cls: type) -> bool:
    """A config dataclass: named ``*Config``, or declaring a range on any of its fields."""
    return cls.__name__.endswith("Config") or any(
        field_range(item) is not None for item in dataclasses.fields(cls)
    )


def held_dataclasses(cls: type) -> Iterator[type]:
    """The dataclasses the fields of ``cls`` hold (its nested configs)."""
    for hint in typing.get_type_hints(cls).values():
        if isinstance(hint, type) and dataclasses.is_dataclass(hint):
            yield hint


def config_classes(module_names: Iterator[str]) -> list[type]:
    """Every config dataclass defined in the modules, and every dataclass a config holds."""
    found: dict[str, type] = {}
    todo = [
        cls
        for name in module_names
        for cls in vars(importlib.import_module(name)).values()
        if isinstance(cls, type) and dataclasses.is_dataclass(cls) and cls.__module__ == name
        if is_config(cls)
    ]
    while todo:
        cls = todo.pop()
        key = f"{cls.__module__}.{cls.__qualname__}"
        if key not in found:
            found[key] = cls
            todo.extend(held_dataclasses(cls))
    return [found[key] for key in sorted(found)]


CONFIGS = config_classes(stack_modules())
"""The stack's config dataclasses (tests/schema/test_config_ranges.py checks their behaviour too)."""


def test_the_walk_finds_the_configs_of_every_layer() -> None:
    names = {cls.__name__ for cls in CONFIGS}
    assert {
        "FPDESOConfig",
        "FuzzyPDConfig",
        "SMMParameters",
        "StampPolicy",
        "PlantConfig",
        "BridgeConfig",
        "AdmissionConfig",
        "LinkConfig",
        "BoardConfig",
        "EmulatorConfig",
        "RecorderConfig",
    } <= names


def numeric_fields(cls: type) -> list[dataclasses.Field[object]]:
    """The fields of ``cls`` given to it that hold a number or a tuple of numbers (optional ones too)."""
    hints = typing.get_type_hints(cls)
    found = []
    for item in dataclasses.fields(cls):
        if not item.init:
            continue  # derived from the others
        hint = numeric_hint(hints[item.name])
        elements = set(typing.get_args(hint)) - {Ellipsis} if typing.get_origin(hint) is tuple else {hint}
        if elements and elements <= {int, float}:
            found.append(item)
    return found


def unranged(cls: type) -> list[str]:
    """Names of the numeric fields of ``cls`` that declare no range."""
    return [item.name for item in numeric_fields(cls) if field_range(item) is None]


def test_every_numeric_field_of_every_config_declares_its_range() -> None:
    missing = [f"{cls.__module__}.{cls.__qualname__}: {unranged(cls)}" for cls in CONFIGS if unranged(cls)]
    assert not missing, "numeric config fields without a range (smm_schema.ranges):\n" + "\n".join(missing)


@dataclasses.dataclass(frozen=True)
class _ForgetfulConfig:
    """A config whose numbers forgot their range.

    Attributes:
        gain: A gain, > 0 in prose only.
        limits: Optional limits.
        label: Not a number.
    """

    gain: float = 1.0
    limits: tuple[float, float] | None = None
    label: str = ""


def test_the_walk_finds_a_config_that_forgot_a_range() -> None:
    (found,) = config_classes(iter([__name__]))
    assert found is _ForgetfulConfig
    assert unranged(found) == ["gain", "limits"]
