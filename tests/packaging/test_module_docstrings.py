"""Module docstrings under src/ say what the module is in a few lines; reasoning and history live in docs/.

A docstring longer than :data:`MAX_LINES` (counted from the opening to the closing quotes) fails.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"
MAX_LINES = 8
"""Most lines a module docstring may span, quotes included."""


def docstring_lines(source: str) -> int:
    """Lines the module docstring of ``source`` spans, quotes included; 0 without one."""
    body = ast.parse(source).body
    if not body or not isinstance(body[0], ast.Expr):
        return 0
    node = body[0]
    if not isinstance(node.value, ast.Constant) or not isinstance(node.value.value, str):
        return 0
    assert node.end_lineno is not None
    return node.end_lineno - node.lineno + 1


def long_docstrings(root: Path, limit: int = MAX_LINES) -> dict[str, int]:
    """Every ``*.py`` under ``root`` whose module docstring spans more than ``limit`` lines: path -> lines."""
    found = {}
    for path in sorted(root.rglob("*.py")):
        lines = docstring_lines(path.read_text(encoding="utf-8"))
        if lines > limit:
            found[path.relative_to(root).as_posix()] = lines
    return found


def test_module_docstrings_are_short() -> None:
    long = long_docstrings(SRC)
    assert not long, f"module docstrings over {MAX_LINES} lines (move the reasoning to docs/): {long}"


def _write(path: Path, docstring_body_lines: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    body = "\n".join(f"line {k}" for k in range(docstring_body_lines))
    path.write_text(f'"""Title.\n{body}\n"""\n\nX = 1\n', encoding="utf-8")


def test_a_planted_long_docstring_is_found(tmp_path: Path) -> None:
    _write(tmp_path / "pkg" / "pkg" / "long.py", MAX_LINES - 1)  # title + body + closing quotes = limit + 1
    _write(tmp_path / "pkg" / "pkg" / "fits.py", MAX_LINES - 2)  # exactly the limit
    (tmp_path / "pkg" / "pkg" / "none.py").write_text("X = 1\n", encoding="utf-8")
    (tmp_path / "pkg" / "pkg" / "one_line.py").write_text('"""One line."""\n', encoding="utf-8")
    assert long_docstrings(tmp_path) == {"pkg/pkg/long.py": MAX_LINES + 1}


@pytest.mark.parametrize(
    ("source", "lines"),
    [
        ('"""One line."""\n', 1),
        ('#!/usr/bin/env python3\n"""Title.\n\nBody.\n"""\n', 4),
        ('r"""Raw \\d."""\n', 1),
        ('from __future__ import annotations\n"""Not a docstring."""\n', 0),
        ("X = 1\n", 0),
        ("", 0),
    ],
)
def test_docstring_lines_counts_the_module_docstring_only(source: str, lines: int) -> None:
    assert docstring_lines(source) == lines
