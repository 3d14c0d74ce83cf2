"""The direct loop in the graph description: one process hosting hw_bridge_node and controller_node."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import (
    CONTROLLER_NODE,
    DIRECT_LOOP,
    EMULATOR_NODE,
    HW_NODE,
    RECORDER_NODE,
    expected_publishers,
    parameter_overrides,
)
from smm_bringup.graph_options import GraphOptions
from smm_bringup.launcher import board_line, read_line, with_board_status
from smm_bringup.parameter_files import load_parameter_file

DIRECT = GraphOptions(plant="hardware", clock_mode="realtime", loop="direct", scenario="case1")


def test_the_direct_loop_replaces_the_bridge_and_the_controller_by_one_process() -> None:
    specs = build_graph(DIRECT)
    assert [spec.name for spec in specs] == [EMULATOR_NODE, DIRECT_LOOP]
    host = specs[1]
    assert host.package == "smm_direct_loop"
    assert host.hosts == (CONTROLLER_NODE, HW_NODE)
    assert host.node_class == ""  # never composed: it owns a thread of its own
    arguments = host.ros_arguments()
    assert "__node:=" not in " ".join(arguments)  # each hosted node keeps its own name
    assert arguments[:3] == ["--ros-args", "-r", "__ns:=/smm"]
    assert host.rt_priority == 50  # the loop's priority; the emulator runs above it
    assert specs[0].rt_priority == 70


def test_the_hosted_nodes_get_what_the_topics_loop_gives_them() -> None:
    """Same parameter files and the same overrides: nothing is re-tuned for the direct loop."""
    topics = {spec.name: spec for spec in build_graph(GraphOptions(**{**DIRECT.__dict__, "loop": "topics"}))}
    host = build_graph(DIRECT)[1]
    assert host.parameter_files == topics[CONTROLLER_NODE].parameter_files
    for name in (CONTROLLER_NODE, HW_NODE):
        hosted: dict[str, Any] = {}
        for path in host.parameter_files:  # rcl applies each file's sections by the hosted node's own name
            hosted.update(load_parameter_file(path, f"/smm/{name}"))
        hosted.update(
            {key: list(value) if isinstance(value, tuple) else value for key, value in host.parameters}
        )
        assert parameter_overrides(topics[name]).items() <= hosted.items(), name
    bridge_names = {name for name, _ in topics[HW_NODE].parameters}
    controller_names = {name for name, _ in topics[CONTROLLER_NODE].parameters}
    assert not bridge_names & controller_names  # -p reaches both nodes: each takes the names it declares


@pytest.mark.parametrize(
    "changes", [{"plant": "sim"}, {"chain": "split"}, {"reference": "node"}, {"loop": "sideways"}]
)
def test_the_direct_loop_needs_hardware_a_fused_chain_and_the_reference_in_the_controller(
    changes: dict[str, Any],
) -> None:
    with pytest.raises(ValueError, match="loop"):
        GraphOptions(**{**DIRECT.__dict__, **changes})


def test_recording_waits_for_the_direct_loop_publishers_before_the_board_starts(tmp_path: Path) -> None:
    specs = build_graph(GraphOptions(**{**DIRECT.__dict__, "record": str(tmp_path / "bag")}))
    assert specs[0].name == RECORDER_NODE
    expected = expected_publishers(specs)
    for topic in (
        "torque_command",
        "controller_internals",
        "reference",
        "joint_states",
        "hw_bridge_internals",
    ):
        assert expected[f"/smm/{topic}"] == 1
    assert expected["/diagnostics"] == 2  # two nodes in the one process


def test_with_a_board_the_direct_loop_runs_alone() -> None:
    specs = build_graph(GraphOptions(**{**DIRECT.__dict__, "board": "10.0.0.7:6000"}))
    assert [spec.name for spec in specs] == [DIRECT_LOOP]
    assert ("link.board_address", "10.0.0.7") in specs[0].parameters


def test_the_emulator_writes_its_status_where_the_launcher_reads_it(tmp_path: Path) -> None:
    status = tmp_path / "board.json"
    specs = with_board_status(build_graph(DIRECT), status)
    assert ("status-file", str(status)) in specs[0].parameters
    assert specs[1] == build_graph(DIRECT)[1]
    from smm_bench_emulator.cli import build_parser, from_ros_arguments

    parsed = build_parser().parse_args(from_ros_arguments(specs[0].ros_arguments()))
    assert parsed.status_file == str(status)


def test_the_closing_line_is_the_emulator_counters(tmp_path: Path) -> None:
    status = tmp_path / "board.json"
    status.write_text(
        json.dumps(
            {"late_commands": 3, "enabled_ticks": 400, "latency_p50_us": 120.4, "latency_p99_us": 280.6}
        )
    )
    assert board_line(status, real_board=False) == (
        "board: late 3 of 400 enabled ticks (0.75 %), feedback->command p50 120 us, p99 281 us"
    )
    status.write_text(
        json.dumps(
            {
                "late_commands": 300,
                "enabled_ticks": 400,
                "latency_p50_us": None,
                "latency_p99_us": None,
                "control_divider": 4,
            }
        )
    )
    assert board_line(status, real_board=False) == (  # 250 Hz control: the board's count is per tick
        "board: late 300 of 400 enabled ticks (75.00 %) (its count per tick: it holds 3 of every 4), "
        "feedback->command no enabled command"
    )
    assert board_line(tmp_path / "missing.json", real_board=False).startswith("board: no end-of-run status")
    assert "host" in board_line(status, real_board=True)  # a real board: what the host knows, and where
    assert read_line(status) is None  # an emulator that gives no read time
    status.write_text(
        json.dumps(
            {
                "late_commands": 3,
                "enabled_ticks": 400,
                "latency_p50_us": 120.4,
                "latency_p99_us": 280.6,
                "read_latency_p50_us": 150.2,
                "read_latency_p99_us": 390.7,
            }
        )
    )
    assert board_line(status, real_board=False).endswith("p50 120 us, p99 281 us")
    assert read_line(status) == (
        "board: (arrival is the kernel's receive time; the emulator process read them at p50 150 us, "
        "p99 391 us, its own wake-up included)"
    )


def test_the_launch_file_starts_the_direct_loop_without_renaming_its_nodes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    sys.path.insert(0, str(Path(__file__).parent))
    try:
        from test_graph_description import _launched_nodes
    finally:
        sys.path.pop(0)
    nodes = _launched_nodes(
        monkeypatch, {"plant": "hardware", "clock_mode": "realtime", "loop": "direct", "scenario": "case1"}
    )
    host = build_graph(DIRECT)[1]
    assert nodes[1].kwargs["executable"] == DIRECT_LOOP
    assert "name" not in nodes[1].kwargs
    *files, overrides = nodes[1].kwargs["parameters"]
    assert tuple(files) == host.parameter_files
    assert overrides == {k: list(v) if isinstance(v, tuple) else v for k, v in host.parameters}
