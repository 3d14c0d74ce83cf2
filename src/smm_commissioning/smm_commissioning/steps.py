"""The commissioning's state in ``--out DIR``: which step passed, in order; the one report of all steps."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Final

from smm_commissioning.errors import StepOrderError

__all__ = [
    "COMMISSIONED",
    "STATE_FILE",
    "STEPS",
    "passed_steps",
    "record_step",
    "require",
    "step_entry",
    "write_report",
]

STEPS: Final[tuple[str, ...]] = ("probe", "jog", "identify", "tune", "verify")
"""The steps, in the order they must pass."""
STATE_FILE: Final[str] = "state.json"
REPORT_FILE: Final[str] = "REPORT.md"
COMMISSIONED: Final[str] = "commissioned.yaml"
"""What ``verify`` writes when the bench is ready: every parameter (smm-launch --params-file)."""


def _load(out: Path) -> dict[str, Any]:
    path = out / STATE_FILE
    if not path.is_file():
        return {}
    try:
        state = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise StepOrderError(
            f"{path} is unreadable ({error}): start again from probe in a new --out"
        ) from error
    if not isinstance(state, dict):
        raise StepOrderError(f"{path} is not a state file: start again from probe in a new --out")
    return state


def passed_steps(out: Path) -> list[str]:
    """The steps that passed, in order (a step counts only if every one before it passed)."""
    state = _load(out)
    done = []
    for step in STEPS:
        if not state.get(step, {}).get("passed"):
            break
        done.append(step)
    return done


def step_entry(out: Path, step: str) -> dict[str, Any]:
    """What ``step`` recorded (its summary), {} if it never ran."""
    entry = _load(out).get(step, {})
    return dict(entry) if isinstance(entry, dict) else {}


def require(out: Path, step: str) -> None:
    """Refuses ``step`` unless the one before it passed.

    Raises:
        StepOrderError: The previous step has not passed (with which and how to get on).
    """
    index = STEPS.index(step)
    if index == 0:
        return
    previous = STEPS[index - 1]
    if previous not in passed_steps(out):
        entry = step_entry(out, previous)
        why = f" (it failed: {entry['why']})" if entry.get("why") else " (it has not run)"
        raise StepOrderError(
            f"{step} needs {previous} to have passed in {out}{why}: run smm-commission {previous} first"
        )


def record_step(out: Path, step: str, passed: bool, summary: dict[str, Any], why: str = "") -> None:
    """Writes ``step``'s outcome; the steps after it are forgotten (they ran on what it replaced).

    ``DIR/commissioned.yaml`` is removed unless ``verify`` passed: it would hold what no longer holds.
    """
    state = _load(out)
    index = STEPS.index(step)
    for later in STEPS[index:]:
        state.pop(later, None)
    state[step] = {"passed": passed, "why": why, **summary}
    out.mkdir(parents=True, exist_ok=True)
    if not (step == STEPS[-1] and passed):
        (out / COMMISSIONED).unlink(missing_ok=True)
    (out / STATE_FILE).write_text(json.dumps(state, indent=2, sort_keys=True) + "\n", encoding="utf-8")


def write_report(out: Path) -> Path:
    """``DIR/REPORT.md``: the sections of every step that ran (``DIR/<step>.md``), in order."""
    parts = ["# Commissioning report\n"]
    done = passed_steps(out)
    parts.append(f"Steps passed: {', '.join(done) if done else 'none'}.\n")
    for step in STEPS:
        section = out / f"{step}.md"
        if section.is_file() and step in _load(out):
            parts.append(section.read_text(encoding="utf-8"))
    path = out / REPORT_FILE
    path.write_text("\n".join(parts), encoding="utf-8")
    return path
