"""The CANopen link's graph: its default rate, one SYNC a control period, the SYNC clock in real time."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import NodeSpec
from smm_bringup.graph_options import CANOPEN_REALTIME_RATE_HZ, GraphOptions, default_control_rate
from smm_bringup.launcher import arguments_from_options, build_parser, options_from_arguments
from smm_hw_bridge.control_rate import CONTROL_RATES_HZ

CANOPEN = ["--plant", "hardware", "--link", "canopen"]


def _bridge(options: GraphOptions) -> dict[str, Any]:
    specs: tuple[NodeSpec, ...] = build_graph(options)
    bridge = next(spec for spec in specs if spec.name in ("hw_bridge_node", "direct_loop"))
    return dict(bridge.parameters)


def _emulator(options: GraphOptions) -> dict[str, Any]:
    return dict(next(spec for spec in build_graph(options) if spec.name == "smm_bench_emulator").parameters)


def test_the_canopen_default_rate_in_real_time_is_offered_and_lockstep_keeps_1_khz() -> None:
    assert CANOPEN_REALTIME_RATE_HZ in CONTROL_RATES_HZ
    assert default_control_rate("canopen", "realtime") == CANOPEN_REALTIME_RATE_HZ
    assert default_control_rate("canopen", "lockstep") == 1000
    assert default_control_rate("frame", "realtime") == 1000


@pytest.mark.parametrize(
    ("extra", "rate"),
    [
        (["--clock-mode", "realtime"], CANOPEN_REALTIME_RATE_HZ),
        (["--clock-mode", "lockstep"], 1000),
        (["--clock-mode", "realtime", "--control-rate", "500"], 500),
        (["--clock-mode", "realtime", "--control-rate", "1000"], 1000),
    ],
)
def test_smm_launch_takes_the_links_default_rate_unless_one_is_given(extra: list[str], rate: int) -> None:
    options = options_from_arguments(build_parser().parse_args([*CANOPEN, *extra]))
    assert options.control_rate == rate
    again = options_from_arguments(build_parser().parse_args(arguments_from_options(options)))
    assert again == options  # an explicit 1000 Hz stays 1000 Hz


@pytest.mark.parametrize("rate", [1000, 500, 250, 200, 100])
def test_real_time_canopen_sends_one_sync_a_control_period_from_the_bridges_loop(rate: int) -> None:
    options = GraphOptions(plant="hardware", link="canopen", clock_mode="realtime", control_rate=rate)
    divider = 1000 // rate
    bridge = _bridge(options)
    assert bridge["canopen.sync_clock"] is True
    assert "canopen.sync_on_enabled" not in bridge
    if divider > 1:
        assert bridge["bridge.control_divider"] == divider
        assert bridge["canopen.period_us"] == 1000 * divider
        assert bridge["canopen.receive_deadline_ms"] == 10 * divider
    emulator = _emulator(options)
    assert emulator.get("control-divider", 1) == divider and "mode" not in emulator


def test_lockstep_canopen_keeps_the_sync_after_the_setpoints() -> None:
    bridge = _bridge(GraphOptions(plant="hardware", link="canopen", clock_mode="lockstep", control_rate=200))
    assert bridge["canopen.sync_on_enabled"] is True and "canopen.sync_clock" not in bridge
    assert bridge["canopen.period_us"] == 5000


@pytest.mark.parametrize("link", ["canopen", "frame"])
def test_the_bridge_knows_the_runs_planned_length_and_ends_an_external_boards_run_itself(link: str) -> None:
    """The emulated bench falls silent at its end: a fault after the planned length leaves the verdict."""
    options = GraphOptions(plant="hardware", link=link, clock_mode="realtime", duration=20.0)
    assert _bridge(options)["verdict.planned_s"] == 20.0 == _emulator(options)["duration"]
    board = "external" if link == "canopen" else "127.0.0.1:50101"
    external = _bridge(
        GraphOptions(plant="hardware", link=link, clock_mode="realtime", duration=20.0, board=board)
    )
    assert (
        external["verdict.planned_s"] == 20.0 and external["verdict.ends_run"] is True
    )  # nothing else ends it
    emulated = _bridge(options)
    assert "verdict.ends_run" not in emulated  # the emulated bench ends its run itself
    assert "verdict.planned_s" not in _bridge(
        GraphOptions(plant="hardware", link=link, clock_mode="realtime")
    )


def test_the_canopen_valve_units_are_the_nominal_valves_and_yield_to_the_users(tmp_path: Path) -> None:
    """The bridge's gain on the emulated CANopen bench is the nominal valve's (a bench file's truths are not
    told to the host, as on the frame link); a parameter file's own gain wins over it."""
    bench = tmp_path / "bench.yaml"
    bench.write_text("full_scale_torque: [8.0, 16.0]\n")
    options = GraphOptions(plant="hardware", link="canopen", bench_file=str(bench))
    assert _bridge(options)["bridge.valve.gain"] == (16384 / 10.0, 16384 / 10.0)
    mine = tmp_path / "mine.yaml"
    mine.write_text(
        "/**/hw_bridge_node:\n  ros__parameters:\n    bridge:\n      valve:\n        gain: [1000.0, 1000.0]\n"
    )
    options = GraphOptions(plant="hardware", link="canopen", bench_file=str(bench), params_files=(str(mine),))
    bridge = _bridge(options)
    assert "bridge.valve.gain" not in bridge  # the file's 1000 reaches the node unchanged
    assert bridge["bridge.valve.code_limit"] == (16384, 16384)  # what the file leaves out stays the default
