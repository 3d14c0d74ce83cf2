"""smm-launch --respawn: an exited node starts again after the delay, up to the limit; the recorder never."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from smm_bringup.graph_nodes import RECORDER_NODE, SIM_NODE, NodeSpec
from smm_bringup.launcher import run
from smm_bringup.supervisor import (
    EXIT_CONFIGURATION_ERROR,
    EXIT_NODE_FAILED,
    EXIT_NOT_CONTROLLED,
    EXIT_OK,
    RespawnPolicy,
    launch_processes,
)


def _script(folder: Path, name: str, body: str) -> None:
    path = folder / name
    path.write_text(f"#!/bin/sh\n{body}\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)


@pytest.fixture
def nodes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Two fake node executables on PATH: ``crasher`` (records each start; SIGKILLs itself while fewer than
    ``$CRASHES`` starts are recorded, else waits) and ``plant`` (completes once ``crasher`` started
    ``$STARTS`` times, else waits)."""
    starts = tmp_path / "starts"
    _script(
        tmp_path,
        "crasher",
        f'echo $$ >> {starts}\nif [ "$(wc -l < {starts})" -le "$CRASHES" ]; then kill -9 $$; fi\n'
        "while true; do sleep 0.05; done",
    )
    _script(
        tmp_path,
        "plant",
        f'while [ "$(cat {starts} 2>/dev/null | wc -l)" -lt "$STARTS" ]; do sleep 0.05; done\nexit 0',
    )
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    return starts


def _graph() -> list[NodeSpec]:
    return [
        NodeSpec("no_such_package", "plant", SIM_NODE, "m:C"),
        NodeSpec("no_such_package", "crasher", "controller_node", "m:C"),
    ]


def test_a_killed_node_is_started_again_and_the_run_completes(
    nodes: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CRASHES", "2")  # killed at its 1st and 2nd start; the 3rd runs
    monkeypatch.setenv("STARTS", "3")
    code = launch_processes(_graph(), stop_grace_s=2.0, respawn=RespawnPolicy(delay_s=0.05, limit=5))
    assert code == EXIT_OK
    pids = nodes.read_text().split()
    assert len(pids) == 3 and len(set(pids)) == 3  # three processes, the same command


def test_past_the_limit_the_graph_stops_as_a_node_failure(
    nodes: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CRASHES", "100")
    monkeypatch.setenv("STARTS", "1000")
    code = launch_processes(_graph(), stop_grace_s=2.0, respawn=RespawnPolicy(delay_s=0.0, limit=2))
    assert code == EXIT_NODE_FAILED
    assert len(nodes.read_text().split()) == 3  # the first start and two respawns


def test_without_respawn_a_killed_node_stops_the_graph(nodes: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CRASHES", "1")
    monkeypatch.setenv("STARTS", "2")
    assert launch_processes(_graph(), stop_grace_s=2.0) == EXIT_NODE_FAILED
    assert len(nodes.read_text().split()) == 1


@pytest.mark.parametrize("respawn", [None, RespawnPolicy(delay_s=0.0, limit=5)])
def test_a_loop_that_ends_its_run_uncontrolled_stops_the_graph_with_exit_3(
    nodes: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, respawn: RespawnPolicy | None
) -> None:
    _script(tmp_path, "stopper", f"echo $$ >> {nodes}\nexit 3")  # as hw_bridge_node at a safety stop
    monkeypatch.setenv("STARTS", "1000")  # the plant never completes
    graph = [_graph()[0], NodeSpec("no_such_package", "stopper", "hw_bridge_node", "m:C")]
    assert launch_processes(graph, stop_grace_s=2.0, respawn=respawn) == EXIT_NOT_CONTROLLED
    assert len(nodes.read_text().split()) == 1  # never started again


@pytest.mark.parametrize("name", ["direct_loop", "hw_bridge_node"])
def test_a_loop_ending_its_run_uncontrolled_is_told_as_such_and_its_exit_0_as_completion(
    nodes: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    name: str,
) -> None:
    monkeypatch.setenv("STARTS", "1000")  # the plant never completes
    for code, said, exit_code in (
        (3, "ended the run: it did not control", EXIT_NOT_CONTROLLED),
        (0, "completed its run", 0),
    ):
        _script(tmp_path, "stopper", f"echo $$ >> {nodes}\nexit {code}")  # as direct_loop at its end
        graph = [_graph()[0], NodeSpec("no_such_package", "stopper", name, "m:C")]
        assert launch_processes(graph, stop_grace_s=2.0) == exit_code
        assert f"{name} {said}" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("name", "code", "respawned"),
    [
        ("controller_node", -9, True),
        ("controller_node", 0, True),  # launch's respawn: any exit while the graph runs
        ("direct_loop", 1, True),
        (RECORDER_NODE, -9, False),  # its bag folder exists: a new recorder could not write it
        (SIM_NODE, 0, False),  # the plant completed the run
        (SIM_NODE, 3, False),  # the plant completed a run that did not control
        ("direct_loop", 3, False),  # the loop ended a run that did not control (a safety stop): final
        ("direct_loop", 0, False),  # the loop ended an external board's run after its --duration
        ("hw_bridge_node", 3, False),
        (SIM_NODE, -9, True),
    ],
)
def test_which_exits_are_respawned(name: str, code: int, respawned: bool) -> None:
    assert RespawnPolicy().applies(NodeSpec("p", "e", name, "m:C"), code) is respawned


@pytest.mark.parametrize(
    ("delay", "limit"), [(-1.0, 3), (61.0, 3), (1.0, 0), (1.0, 10_001), (True, 3), (1.0, 2.5)]
)
def test_a_delay_or_limit_out_of_range_is_refused(delay: float, limit: int) -> None:
    with pytest.raises(ValueError, match="respawn"):
        RespawnPolicy(delay, limit)


@pytest.mark.parametrize(
    "arguments",
    [
        ["--respawn", "--respawn-delay", "-1"],
        ["--respawn", "--respawn-limit", "0"],
        ["--respawn-limit", "3"],  # an option of --respawn only
        ["--respawn", "--composed"],
    ],
)
def test_smm_launch_refuses_bad_respawn_options_with_exit_2(
    arguments: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert run([*arguments, "--dry-run"]) == EXIT_CONFIGURATION_ERROR
    assert "respawn" in capsys.readouterr().err
