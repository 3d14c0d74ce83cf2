"""A fifth law, defined in its own module and registered only through the ``smm_controller.laws`` entry point.

The module (tests/extension_law/smm_extra_law.py) is installed the way a package would be: a ``.dist-info``
with the entry point in a temporary folder on the path (``PYTHONPATH`` for started processes). The node,
the offline loop, rerun, a sweep, ``smm-launch --algorithm`` and the demo's choices then accept it with no
other change.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from smm_controller.laws import LAW_GROUP, get_law, law_names, law_table

PLUGIN = Path(__file__).resolve().parents[1] / "extension_law"
NAME = "linpd"


def install(site: Path) -> None:
    """Writes the distribution's metadata with the entry point into ``site``."""
    info = site / "smm_extra_law-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: smm-extra-law\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{LAW_GROUP}]\n{NAME} = smm_extra_law:LAW\n")


@pytest.fixture
def fifth_law(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[dict[str, str]]:
    """The fifth law installed for this process and for the processes it starts (their environment)."""
    site = tmp_path / "site"
    install(site)
    monkeypatch.syspath_prepend(str(PLUGIN))
    monkeypatch.syspath_prepend(str(site))
    path = os.pathsep.join([str(site), str(PLUGIN), os.environ.get("PYTHONPATH", "")])
    monkeypatch.setenv("PYTHONPATH", path)
    law_table.cache_clear()
    try:
        yield {"PYTHONPATH": path}
    finally:
        monkeypatch.undo()
        sys.modules.pop("smm_extra_law", None)
        sys.modules.pop("smm_extra_law_batch", None)
        law_table.cache_clear()


def test_without_the_entry_point_the_law_is_unknown() -> None:
    assert NAME not in law_names()


def test_the_table_takes_the_registered_law_after_the_paper_laws(fifth_law: dict[str, str]) -> None:
    assert law_names()[-1] == NAME and len(law_names()) == 5
    assert get_law(NAME).label == "linear PD" and not get_law(NAME).uses_disturbance_estimate


def test_the_offline_loop_runs_it(fifth_law: dict[str, str]) -> None:
    from smm_analysis.closed_loop import run_closed_loop
    from smm_analysis.scenarios import get_scenario

    run = run_closed_loop(get_scenario("case2").with_duration(0.5), NAME, seed=1)
    assert run.controller == NAME and "controller.tau" in run.internals
    assert np.all(np.isfinite(run.command_torque))
    assert np.max(np.abs(run.desired_position - run.position)) < 0.01  # it tracks the 1 rad sine


def test_rerun_builds_its_chain_from_parameters(fifth_law: dict[str, str]) -> None:
    from smm_analysis.runs.rerun import chain_settings
    from smm_extra_law import LinearPD

    settings = chain_settings({"algorithm": NAME, f"{NAME}.kp": [500.0, 400.0]})
    chain = settings.build()
    assert isinstance(chain.controller, LinearPD) and chain.fleso is None
    assert settings.law.kp == (500.0, 400.0) and settings.flip_size == (0.0, 0.0)
    torque = chain.step_floats((0.01, 0.0), (0.0, 0.0), ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0)), 1e-3)
    assert torque[0] == pytest.approx(-5.0 - 60.0 * 0.0, abs=1.0)


def test_a_sweep_runs_its_batched_twin(fifth_law: dict[str, str], tmp_path: Path) -> None:
    from smm_analysis.sweep.execute import batches, run_sweep
    from smm_analysis.sweep.spec import parse_spec

    spec = parse_spec(
        {
            "name": "fifth",
            "controller": NAME,
            "scenarios": ["case2"],
            "duration": 0.05,
            "gains": {f"{NAME}.kp[0]": {"grid": [600.0, 900.0]}},
            "objectives": ["RMS_alpha"],
        }
    )
    assert run_sweep(spec, tmp_path / "sweep") == len(batches(spec)) >= 1
    assert list((tmp_path / "sweep" / "parts").glob("*.parquet"))


def test_the_demo_offers_it(fifth_law: dict[str, str]) -> None:
    from smm_bringup.demo import build_parser

    assert build_parser().parse_args(["--controllers", NAME, "fpdeso"]).controllers == [NAME, "fpdeso"]


@pytest.mark.ros
def test_the_node_runs_it_and_takes_its_gains(fifth_law: dict[str, str], ros_context: Any) -> None:
    from rclpy.parameter import Parameter
    from smm_controller.chain import build_chain
    from smm_controller.controller_node import ControllerNode
    from smm_extra_law import LinearPD, LinearPDConfig
    from smm_msgs_py.conversions import JointSample

    from smm_dynamics import SMMParameters
    from smm_msgs_py import topics
    from smm_node_runtime import values_of

    node = ControllerNode(
        context=ros_context,
        parameter_overrides={"algorithm": NAME, "chain": "internal", "reference_source": "internal"},
    )
    try:
        assert isinstance(node.controller, LinearPD) and node.chain is not None and node.chain.fleso is None
        (result,) = node.set_parameters([Parameter(f"{NAME}.kp", value=[700.0, 700.0])])
        assert result.successful and node.controller.config.kp == (700.0, 700.0)
        sample = JointSample(1_000_000, np.array([0.01, -0.01]), effort=np.zeros(2))
        node.take_input(topics.JOINT_STATES, sample, values_of(sample))
        twin = build_chain(NAME, SMMParameters(), law=LinearPD(LinearPDConfig(kp=(700.0, 700.0))))
        expected = twin.step_floats((0.01, -0.01), (0.0, 0.0), node.core.last_reference, 1e-3)
        assert node.answered == 1 and tuple(node.controller.internals["tau"]) == expected
    finally:
        node.destroy_node()  # type: ignore[no-untyped-call]


@pytest.mark.ros
def test_smm_launch_runs_it_in_lockstep(fifth_law: dict[str, str], ros_processes: Any) -> None:
    launcher = ros_processes.start(
        "smm-launch-fifth-law",
        [sys.executable, "-m", "smm_bringup.launcher", "--algorithm", NAME, "--duration", "0.2"],
    )
    code = launcher.popen.wait(timeout=150)
    assert code == 0, launcher.logs()
    assert "smm_sim_node completed its run" in launcher.logs()
