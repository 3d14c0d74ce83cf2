"""Mutation testing of the pure modules with mutmut 3 (`make mutation`; docs/TESTING.md).

mutmut 3 expects one ``src/<package>`` tree; ours has one ament package per directory
(``src/<pkg>/<pkg>/``). For each group of modules of one package this driver stages a work directory
``out/mutation/work/<pkg>/`` holding ``src/<pkg>`` (a copy of the package), ``tests/`` and a
``pyproject.toml`` with a ``[tool.mutmut]`` section, runs ``mutmut run`` there, and reads mutmut's
per-file results (``mutants/<path>.meta``). The report is written to ``out/mutation/report.md`` and
``report.json``; one JSON per measured module in ``out/mutation/results/`` keeps earlier figures, so
modules can be run in parts (``--modules``).

Add a module: one line in MODULES. A module whose file does not exist (yet) is reported as missing.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "out" / "mutation"
EQUIVALENT_FILE = Path(__file__).resolve().with_name("mutation_equivalent.txt")

CONTROLLER_TESTS = ("tests/controller",)
DYNAMICS_TESTS = ("tests/dynamics",)
SCHEMA_TESTS = ("tests/schema", "tests/dynamics/test_dynamics_arguments.py")
#: The fuzzy engine is called by nearly every controller test; its own tests judge it (and keep it fast).
FUZZY_TESTS = tuple(
    f"tests/controller/test_{name}.py"
    for name in ("fuzzy_tables", "fuzzy", "fuzzy_batch", "fuzzy_pd", "rules")
)


@dataclass(frozen=True)
class Module:
    """A module to mutate, ``<pkg>/<module>.py`` under ``src/<pkg>/``, and the pure tests that judge it."""

    path: str
    tests: tuple[str, ...]
    profile: str = "thorough"
    """Hypothesis profile of its tests (tests/conftest.py), unless ``--profile`` is given."""

    @property
    def package(self) -> str:
        """The package directory name, e.g. ``smm_controller``."""
        return self.path.split("/", 1)[0]

    @property
    def source(self) -> Path:
        """Path of the module in the repository."""
        return REPO / "src" / self.package / self.path


#: The modules under mutation and their fast (pure unit) test layers. mutmut runs, for each mutant, only the
#: selected tests that call the mutated function. One line per module. The dynamics' properties run the `ci`
#: profile's 100 examples: at `thorough`'s 1000 their run alone would take most of the hour.
MODULES: tuple[Module, ...] = (
    Module("smm_dynamics/model.py", DYNAMICS_TESTS, "ci"),
    Module("smm_dynamics/kinematics.py", DYNAMICS_TESTS, "ci"),
    Module("smm_dynamics/integration.py", DYNAMICS_TESTS, "ci"),
    Module("smm_dynamics/fast_path.py", DYNAMICS_TESTS, "ci"),
    Module("smm_dynamics/_terms.py", DYNAMICS_TESTS, "ci"),
    Module("smm_dynamics/_arrays.py", DYNAMICS_TESTS, "ci"),
    Module("smm_dynamics/parameters.py", DYNAMICS_TESTS, "ci"),
    Module("smm_dynamics/valve.py", DYNAMICS_TESTS, "ci"),
    Module("smm_schema/ranges.py", SCHEMA_TESTS, "ci"),
    Module("smm_controller/td.py", CONTROLLER_TESTS),
    Module("smm_controller/fleso.py", CONTROLLER_TESTS),
    Module("smm_controller/fuzzy.py", FUZZY_TESTS),
    Module("smm_controller/fuzzy_tables.py", FUZZY_TESTS),
    Module("smm_controller/fuzzy_batch.py", FUZZY_TESTS),
    Module("smm_controller/fuzzy_pd.py", CONTROLLER_TESTS),
    Module("smm_controller/rules.py", FUZZY_TESTS),
    Module("smm_controller/fpdeso.py", CONTROLLER_TESTS),
    Module("smm_controller/baselines.py", CONTROLLER_TESTS),
    Module("smm_controller/reference.py", CONTROLLER_TESTS),
    Module("smm_controller/chain.py", CONTROLLER_TESTS),
    Module("smm_controller/torque_law.py", CONTROLLER_TESTS),
    Module("smm_controller/model.py", CONTROLLER_TESTS),
    Module("smm_controller/limits.py", ("tests/controller/test_limits.py",)),
    Module("smm_sim/plant.py", ("tests/sim",)),
    Module("smm_analysis/metrics.py", ("tests/analysis/test_analysis_metrics.py",)),
    Module("smm_msgs_py/conversions.py", ("tests/msgs",)),
    Module("smm_hw_bridge/protocol.py", ("tests/hw_bridge/test_protocol.py",)),
    Module("smm_analysis/runs/indices.py", ("tests/analysis/runs/test_indices.py",)),
)

#: mutmut exit codes (mutmut.stats.status_by_exit_code), grouped for the score.
KILLED = frozenset({"killed", "timeout", "caught by type check", "segfault"})
NOT_RUN = frozenset({"not checked", "skipped", "check was interrupted by user"})


@dataclass
class ModuleResult:
    """Outcome of one module: counts per mutmut status, survivors, equivalents."""

    path: str
    status: str  # "measured" | "missing" | "failed" | "not run"
    counts: dict[str, int] = field(default_factory=dict)
    survivors: list[str] = field(default_factory=list)
    equivalent: list[str] = field(default_factory=list)
    seconds: float = 0.0
    measured_at: str = ""
    commit: str = ""
    note: str = ""

    @property
    def total(self) -> int:
        """Mutants generated."""
        return sum(self.counts.values())

    @property
    def killed(self) -> int:
        """Mutants some test failed on (timeouts included)."""
        return sum(n for status, n in self.counts.items() if status in KILLED)

    @property
    def scored(self) -> int:
        """Mutants that count: all run ones less those triaged as equivalent."""
        run = sum(n for status, n in self.counts.items() if status not in NOT_RUN)
        return run - len(self.equivalent)

    @property
    def score(self) -> float | None:
        """Killed / non-equivalent mutants, in percent; None if nothing counts."""
        return 100.0 * self.killed / self.scored if self.scored > 0 else None


def classify(exit_codes: Mapping[str, int | None], equivalent: Iterable[str]) -> ModuleResult:
    """Counts mutmut exit codes by status; survivors and 'no tests' mutants not triaged are survivors."""
    from mutmut.stats import status_by_exit_code  # noqa: PLC0415 (mutmut is a dev tool, only needed here)

    known_equivalent = set(equivalent)
    result = ModuleResult(path="", status="measured")
    for name, code in sorted(exit_codes.items()):
        status = status_by_exit_code[code]
        result.counts[status] = result.counts.get(status, 0) + 1
        if status in KILLED or status in NOT_RUN:
            continue
        if name in known_equivalent:
            result.equivalent.append(name)
        else:
            result.survivors.append(name)
    return result


def read_equivalent(path: Path = EQUIVALENT_FILE) -> dict[str, str]:
    """Mutants triaged as equivalent: ``<mutant name>  # reason`` per line."""
    if not path.exists():
        return {}
    entries: dict[str, str] = {}
    for line in path.read_text().splitlines():
        name, _, reason = line.partition("#")
        if name.strip():
            entries[name.strip()] = reason.strip()
    return entries


def mutmut_config(modules: Sequence[Module], also_copy: Sequence[str] = ()) -> str:
    """The ``[tool.mutmut]`` section for one package's modules (TOML); ``also_copy``: extra paths."""
    packages = {m.package for m in modules}
    if len(packages) != 1:
        raise ValueError(f"one package per mutmut run, got {sorted(packages)}")
    tests = sorted({t for m in modules for t in m.tests})
    package = packages.pop()

    def array(items: Iterable[str]) -> str:
        return "[" + ", ".join(json.dumps(i) for i in items) + "]"

    return "\n".join(
        (
            "[tool.mutmut]",
            f"source_paths = {array([f'src/{package}'])}",
            f"only_mutate = {array(f'src/{m.path}' for m in modules)}",
            f"pytest_add_cli_args_test_selection = {array(tests)}",
            'pytest_add_cli_args = ["-p", "no:cacheprovider", "-m", "not ros and not realtime"]',
            "use_git_change_detection = false",
            f"also_copy = {array(also_copy)}",
            "",
        )
    )


def stage(package: str, modules: Sequence[Module], work: Path) -> None:
    """Creates ``work`` afresh: ``src/<pkg>``, the package's other folders beside it, tests/, pyproject.toml.

    Folders such as ``tools`` or ``config`` keep their place beside the package, as tests find them there.
    """
    if work.exists():
        shutil.rmtree(work)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".hypothesis", "*.egg-info")
    shutil.copytree(REPO / "src" / package / package, work / "src" / package, ignore=ignore)
    siblings = []
    for entry in sorted((REPO / "src" / package).iterdir()):
        if entry.is_dir() and entry.name != package and not entry.name.endswith(".egg-info"):
            shutil.copytree(entry, work / "src" / entry.name, ignore=ignore)
            siblings.append(f"src/{entry.name}")
    shutil.copytree(REPO / "tests", work / "tests", ignore=ignore)
    pyproject = (REPO / "pyproject.toml").read_text()
    if "[tool.mutmut]" in pyproject:
        raise ValueError("pyproject.toml has its own [tool.mutmut]; the driver writes that section")
    (work / "pyproject.toml").write_text(pyproject + "\n" + mutmut_config(modules, siblings))


def mutmut_environment(profile: str) -> dict[str, str]:
    """Environment of a mutmut run: pure tests only (no network namespace), the given Hypothesis profile."""
    env = dict(os.environ)
    env["SMM_TEST_NETNS_FAILURE"] = "mutation testing runs pure unit tests only"
    env["HYPOTHESIS_PROFILE"] = profile
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


def git_commit() -> str:
    """HEAD of the repository, with '+dirty' when the work tree has changes under src/ or tests/."""
    head = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], check=False, cwd=REPO, capture_output=True, text=True
    )
    dirty = subprocess.run(
        ["git", "status", "--porcelain", "src", "tests"],
        check=False,
        cwd=REPO,
        capture_output=True,
        text=True,
    )
    return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def run_package(
    package: str, modules: Sequence[Module], *, max_children: int, profile: str, equivalent: Mapping[str, str]
) -> list[ModuleResult]:
    """Stages and runs mutmut for one package's modules; one result per module."""
    work = OUT / "work" / package
    stage(package, modules, work)
    log = OUT / "logs" / f"{package}.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    print(f"[{package}] mutmut run over {', '.join(m.path for m in modules)} (log: {log})", flush=True)
    commit = git_commit()  # of the sources and tests staged above
    start = time.monotonic()
    with log.open("w") as stream:
        proc = subprocess.run(
            [sys.executable, "-m", "mutmut", "run", "--max-children", str(max_children)],
            cwd=work,
            env=mutmut_environment(profile),
            stdout=stream,
            stderr=subprocess.STDOUT,
            check=False,
        )
    seconds = time.monotonic() - start
    stamp = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    results = []
    for module in modules:
        meta = work / "mutants" / "src" / (module.path + ".meta")
        if proc.returncode != 0 or not meta.exists():
            note = f"mutmut exited {proc.returncode}; see {log.relative_to(REPO)}"
            results.append(ModuleResult(module.path, "failed", seconds=seconds, measured_at=stamp, note=note))
            continue
        exit_codes = json.loads(meta.read_text())["exit_code_by_key"]
        result = classify(exit_codes, equivalent)
        result.path, result.seconds, result.measured_at, result.commit = module.path, seconds, stamp, commit
        result.note = f"{package} run: {seconds:.0f} s for {len(modules)} module(s), profile {profile}"
        results.append(result)
        save_diffs(work, result)
    return results


def save_diffs(work: Path, result: ModuleResult) -> None:
    """Writes ``mutmut show`` of every survivor to out/mutation/survivors/<module>.diff."""
    target = OUT / "survivors" / (result.path.replace("/", ".") + ".diff")
    target.parent.mkdir(parents=True, exist_ok=True)
    chunks = []
    for name in result.survivors:
        shown = subprocess.run(
            [sys.executable, "-m", "mutmut", "show", name],
            check=False,
            cwd=work,
            capture_output=True,
            text=True,
        )
        chunks.append(shown.stdout.rstrip() + "\n")
    target.write_text("\n".join(chunks))


def collect(module: Module, equivalent: Mapping[str, str]) -> ModuleResult | None:
    """What mutmut has saved so far for a module in its work directory; status 'partial' if unfinished."""
    meta = OUT / "work" / module.package / "mutants" / "src" / (module.path + ".meta")
    if not meta.exists():
        return None
    result = classify(json.loads(meta.read_text())["exit_code_by_key"], equivalent)
    not_checked = result.counts.get("not checked", 0)
    result.path, result.commit = module.path, git_commit()
    result.measured_at = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    if not_checked:
        result.status = "partial"
        result.note = f"partial: {result.total - not_checked} of {result.total} mutants run when collected"
    return result


def result_file(path: str) -> Path:
    """Where one module's latest result is kept."""
    return OUT / "results" / (path.replace("/", ".") + ".json")


def save_result(result: ModuleResult) -> None:
    """Keeps one module's result for later reports."""
    target = result_file(result.path)
    target.parent.mkdir(parents=True, exist_ok=True)
    data = {k: v for k, v in vars(result).items()}
    target.write_text(json.dumps(data, indent=2))


def load_result(module: Module, equivalent: Iterable[str] = ()) -> ModuleResult:
    """The latest result of a module (missing source, earlier measurement or not run), triaged anew."""
    if not module.source.exists():
        return ModuleResult(module.path, "missing", note=f"src/{module.package}/{module.path} does not exist")
    target = result_file(module.path)
    if not target.exists():
        return ModuleResult(module.path, "not run")
    result = ModuleResult(**json.loads(target.read_text()))
    known = set(equivalent)
    survivors = sorted(result.survivors + result.equivalent)
    result.equivalent = [name for name in survivors if name in known]
    result.survivors = [name for name in survivors if name not in known]
    return result


def score_text(result: ModuleResult) -> str:
    """The score column: percent (of the mutants run, if partial), or the status when there is no figure."""
    if result.status not in ("measured", "partial"):
        return result.status
    figure = "-" if result.score is None else f"{result.score:.1f} %"
    return figure if result.status == "measured" else f"{figure} (partial)"


def report(results: Sequence[ModuleResult], threshold: float) -> str:
    """The Markdown report: one row per module, then the survivors not triaged."""
    lines = [
        "# Mutation testing report",
        "",
        "| module | mutants | killed | survived | no tests | equivalent | score | measured |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in results:
        lines.append(
            f"| {r.path} | {r.total} | {r.killed} | {r.counts.get('survived', 0)} | "
            f"{r.counts.get('no tests', 0)} | {len(r.equivalent)} | {score_text(r)} | "
            f"{r.measured_at} {r.commit} {r.note} |".rstrip()
        )
    below = [r.path for r in results if r.status == "measured" and (r.score or 0.0) < threshold]
    lines += [
        "",
        f"Score = killed (timeouts included) / (mutants run - equivalent); threshold {threshold:.0f} %.",
    ]
    lines.append(f"Below threshold: {', '.join(below) if below else 'none'}.")
    for r in results:
        if r.survivors:
            lines += ["", f"## Survivors in {r.path} ({len(r.survivors)})", ""]
            lines += [f"- `{name}`" for name in r.survivors]
    return "\n".join(lines) + "\n"


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command line of the driver."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modules", nargs="*", default=None, help="substrings of MODULES paths to run")
    parser.add_argument("--report-only", action="store_true", help="rewrite the report from kept results")
    parser.add_argument(
        "--collect", action="store_true", help="keep the results mutmut has saved so far (a run in progress)"
    )
    parser.add_argument("--max-children", type=int, default=2, help="parallel mutant workers (default 2)")
    parser.add_argument(
        "--profile", default=None, help="Hypothesis profile for every module (default: each module's own)"
    )
    parser.add_argument("--threshold", type=float, default=90.0, help="score per module to reach, percent")
    parser.add_argument("--list", action="store_true", help="list the modules and their tests")
    return parser.parse_args(argv)


def package_profile(modules: Sequence[Module]) -> str:
    """The one Hypothesis profile of a package's modules (one mutmut run per package)."""
    profiles = {m.profile for m in modules}
    if len(profiles) != 1:
        raise ValueError(f"one profile per package run, got {sorted(profiles)}")
    return profiles.pop()


def select(modules: Sequence[Module], patterns: Sequence[str] | None) -> list[Module]:
    """The modules whose path contains one of the patterns (all when None)."""
    if patterns is None:
        return list(modules)
    chosen = [m for m in modules if any(p in m.path for p in patterns)]
    if not chosen:
        raise SystemExit(f"no module matches {list(patterns)}; known: {[m.path for m in modules]}")
    return chosen


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the selected modules, prints the per-module scores, writes the report; 1 if one is below."""
    args = parse_arguments(argv)
    if args.list:
        for m in MODULES:
            print(f"{m.path:32} {' '.join(m.tests)}{'' if m.source.exists() else '  (missing)'}")
        return 0
    equivalent = read_equivalent()
    if args.collect:
        for m in select(MODULES, args.modules):
            partial = collect(m, equivalent)
            if partial is not None:
                save_result(partial)
    elif not args.report_only:
        chosen = [m for m in select(MODULES, args.modules) if m.source.exists()]
        by_package: dict[str, list[Module]] = {}
        for m in chosen:
            by_package.setdefault(m.package, []).append(m)
        for package, modules in by_package.items():
            profile = args.profile or package_profile(modules)
            for result in run_package(
                package, modules, max_children=args.max_children, profile=profile, equivalent=equivalent
            ):
                save_result(result)
                print(f"  {result.path}: {score_text(result)} ({result.killed}/{result.scored})", flush=True)
    results = [load_result(m, equivalent) for m in MODULES]
    text = report(results, args.threshold)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "report.md").write_text(text)
    (OUT / "report.json").write_text(
        json.dumps([vars(r) | {"score": r.score} for r in results], indent=2) + "\n"
    )
    print(text)
    print(f"report: {(OUT / 'report.md').relative_to(REPO)}")
    failing = [
        r
        for r in results
        if r.status == "failed" or (r.status == "measured" and (r.score or 0) < args.threshold)
    ]
    return 1 if failing else 0


if __name__ == "__main__":
    sys.exit(main())
