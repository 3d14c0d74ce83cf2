"""tools/mutation.py: the driver of `make mutation` (staging, mutmut config, scoring, report)."""

from __future__ import annotations

import importlib.util
import sys
import tomllib
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

DRIVER = Path(__file__).resolve().parents[2] / "tools" / "mutation.py"


@pytest.fixture(scope="module")
def driver() -> ModuleType:
    spec = importlib.util.spec_from_file_location("mutation_driver_under_test", DRIVER)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_every_listed_module_is_one_line_with_its_tests(driver: ModuleType) -> None:
    paths = [m.path for m in driver.MODULES]
    assert len(paths) == len(set(paths))
    for module in driver.MODULES:
        assert module.path.count("/") >= 1 and module.path.endswith(".py")  # <pkg>/[subpackage/]module.py
        assert module.tests, module.path
        if module.source.exists():
            for tests in module.tests:
                assert (driver.REPO / tests).exists(), f"{module.path}: {tests} does not exist"


def test_mutmut_config_is_valid_toml_for_one_package(driver: ModuleType) -> None:
    modules = [
        driver.Module("smm_controller/td.py", ("tests/controller",)),
        driver.Module("smm_controller/fleso.py", ("tests/x",)),
    ]
    config = tomllib.loads(driver.mutmut_config(modules, ["src/config"]))["tool"]["mutmut"]
    assert config["source_paths"] == ["src/smm_controller"]
    assert config["only_mutate"] == ["src/smm_controller/td.py", "src/smm_controller/fleso.py"]
    assert config["pytest_add_cli_args_test_selection"] == ["tests/controller", "tests/x"]
    assert config["also_copy"] == ["src/config"]
    with pytest.raises(ValueError, match="one package"):
        driver.mutmut_config([modules[0], driver.Module("smm_sim/plant.py", ("tests/sim",))])


def test_mutmut_runs_deselect_tests_that_start_ros(driver: ModuleType) -> None:
    from _pytest.mark.expression import Expression

    def marked(name: str) -> Any:
        return lambda marker, /, **kwargs: marker == name

    module = driver.Module("smm_controller/td.py", ("tests/controller",))
    cli = tomllib.loads(driver.mutmut_config([module], []))["tool"]["mutmut"]["pytest_add_cli_args"]
    expression = Expression.compile(cli[cli.index("-m") + 1])
    assert not expression.evaluate(marked("ros"))  # node tests in tests/controller
    assert not expression.evaluate(marked("realtime"))
    assert expression.evaluate(marked("slow")) and expression.evaluate(marked(""))


def test_classify_scores_killed_over_non_equivalent(driver: ModuleType) -> None:
    codes = {
        "m.x_f__mutmut_1": 1,
        "m.x_f__mutmut_2": 0,
        "m.x_f__mutmut_3": 0,
        "m.x_f__mutmut_4": 36,
        "m.x_f__mutmut_5": 33,
        "m.x_f__mutmut_6": None,
    }
    result = driver.classify(codes, {"m.x_f__mutmut_3"})
    assert result.counts == {"killed": 1, "survived": 2, "timeout": 1, "no tests": 1, "not checked": 1}
    assert result.killed == 2  # a timeout counts as killed
    assert result.equivalent == ["m.x_f__mutmut_3"]
    assert result.survivors == ["m.x_f__mutmut_2", "m.x_f__mutmut_5"]  # 'no tests' is a survivor
    assert result.scored == 4  # 5 run, less 1 equivalent; 'not checked' does not count
    assert result.score == pytest.approx(50.0)


def test_equivalent_file_lines(driver: ModuleType, tmp_path: Path) -> None:
    path = tmp_path / "equivalent.txt"
    path.write_text("# comment line\n\nm.x_f__mutmut_3  # sign(0) never reached\n")
    assert driver.read_equivalent(path) == {"m.x_f__mutmut_3": "sign(0) never reached"}
    assert driver.read_equivalent(tmp_path / "absent.txt") == {}


def test_missing_module_is_reported_not_run(
    driver: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(driver, "OUT", tmp_path)
    missing = driver.Module("smm_hw_bridge/not_there.py", ("tests/hw_bridge",))
    result = driver.load_result(missing)
    assert result.status == "missing"
    not_run = driver.load_result(driver.Module("smm_controller/td.py", ("tests/controller",)))
    assert not_run.status == "not run"
    text = driver.report([result, not_run], 90.0)
    assert "| smm_hw_bridge/not_there.py |" in text and "missing" in text and "not run" in text


def test_results_round_trip_and_threshold(
    driver: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(driver, "OUT", tmp_path)
    result = driver.classify({"p.x_g__mutmut_1": 1, "p.x_g__mutmut_2": 0}, ())
    result.path = "smm_controller/td.py"
    driver.save_result(result)
    loaded = driver.load_result(driver.Module("smm_controller/td.py", ("tests/controller",)))
    assert loaded.counts == result.counts and loaded.survivors == ["p.x_g__mutmut_2"]
    text = driver.report([loaded], 90.0)
    assert "50.0 %" in text and "Below threshold: smm_controller/td.py." in text
    assert "`p.x_g__mutmut_2`" in text
    triaged = driver.load_result(
        driver.Module("smm_controller/td.py", ("tests/controller",)), {"p.x_g__mutmut_2"}
    )
    assert triaged.equivalent == ["p.x_g__mutmut_2"] and triaged.survivors == []
    assert triaged.score == pytest.approx(100.0)


def test_collect_reads_a_run_in_progress(
    driver: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(driver, "OUT", tmp_path)
    module = driver.Module("smm_controller/td.py", ("tests/controller",))
    assert driver.collect(module, {}) is None
    meta = tmp_path / "work" / "smm_controller" / "mutants" / "src" / "smm_controller" / "td.py.meta"
    meta.parent.mkdir(parents=True)
    meta.write_text('{"exit_code_by_key": {"a__mutmut_1": 1, "a__mutmut_2": null, "a__mutmut_3": 0}}')
    partial = driver.collect(module, {})
    assert partial.status == "partial" and "2 of 3 mutants run" in partial.note
    assert partial.score == pytest.approx(50.0)
    assert driver.score_text(partial) == "50.0 % (partial)"


def test_each_package_run_has_one_profile(driver: ModuleType) -> None:
    dynamics = [m for m in driver.MODULES if m.package == "smm_dynamics"]
    assert dynamics and driver.package_profile(dynamics) == "ci"
    controller = [m for m in driver.MODULES if m.package == "smm_controller"]
    assert driver.package_profile(controller) == "thorough"
    mixed = [
        driver.Module("smm_sim/a.py", ("tests/sim",), "ci"),
        driver.Module("smm_sim/b.py", ("tests/sim",)),
    ]
    with pytest.raises(ValueError, match=r"one profile per package run, got \['ci', 'thorough'\]"):
        driver.package_profile(mixed)
