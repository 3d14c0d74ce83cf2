"""A bad bag or parameters file gets its exit code from ``smm-bag analyze`` and ``rerun`` too."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
from bag.bag_helpers import DAMAGES, flip_chunk_byte, good_bag
from smm_analysis.runs.recorded import load_run
from smm_bag.cli import main
from smm_bag.exit_codes import EXIT_CORRUPT, EXIT_MISSING_TOPICS, EXIT_PARAMS

from smm_bag import MissingTopicsError


@pytest.mark.parametrize(("damage", "code"), [(c[1], c[3]) for c in DAMAGES], ids=[c[0] for c in DAMAGES])
def test_damaged_bag_gets_its_exit_code_from_analyze(
    tmp_path: Path, damage: Callable[[Path], None], code: int, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = good_bag(tmp_path / "bag")
    damage(bag)
    assert main(["analyze", "--quiet", str(bag)]) == code
    assert "smm-bag: error:" in capsys.readouterr().err


def test_corrupt_chunk_is_reported_by_analyze(tmp_path: Path) -> None:
    bag = good_bag(tmp_path / "bag")
    flip_chunk_byte(bag)
    assert main(["analyze", "--quiet", str(bag)]) == EXIT_CORRUPT


def test_missing_topics_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = good_bag(tmp_path / "bag", ("/smm/joint_states",))
    with pytest.raises(MissingTopicsError, match="/smm/reference, /smm/torque_command"):
        load_run(bag)
    assert main(["analyze", "--quiet", str(bag)]) == EXIT_MISSING_TOPICS
    assert main(["rerun", str(bag)]) == EXIT_MISSING_TOPICS
    assert "/smm/reference" in capsys.readouterr().err


def test_bad_params_file_exit_code(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    shutil.copytree(good_bag(tmp_path / "source"), bag)
    params = tmp_path / "params.yaml"
    params.write_text("not: [a, params, file\n")
    assert main(["rerun", str(bag), "--params-file", str(params)]) == EXIT_PARAMS
    params.write_text(
        "/**/controller_node:\n  ros__parameters:\n    fpdeso:\n      fuzzy:\n        kp0: [1.0]\n"
    )
    assert main(["rerun", str(bag), "--params-file", str(params)]) == EXIT_PARAMS
    params.write_text("/**/controller_node:\n  ros__parameters:\n    algorithm: lqr\n")
    assert main(["rerun", str(bag), "--params-file", str(params)]) == EXIT_PARAMS
    assert main(["rerun", str(bag), "--params-file", str(tmp_path / "absent.yaml")]) == EXIT_PARAMS
