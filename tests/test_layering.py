"""What the code may not say (parsed, not run): the laws are listed once, private names stay in their package.

- A literal tuple, list or set naming two or more of the paper's laws exists only in the table
  (``smm_controller/laws.py``); everyone else reads ``law_table()``, ``law_names()`` or ``PAPER_LAWS``. A
  dict literal keyed by two or more laws is refused in the packages too, but for the files that hold the
  paper's own per-law content (published figures, derivations, one study's two runs), listed below.
- No module imports a private module or a private name (leading underscore) of another package.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest
from smm_controller.laws import PAPER_LAWS

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
