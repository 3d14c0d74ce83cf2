"""smm-launch --bench-file: passed to the emulator (on CANopen its supply to the bridge too), refused where
there is no emulator."""

from __future__ import annotations

from pathlib import Path

import pytest
from smm_bench_emulator.bench_file import default_bench
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import DIRECT_LOOP, EMULATOR_NODE, HW_NODE
from smm_bringup.graph_options import GraphOptions
from smm_bringup.launcher import arguments_from_options, build_parser, options_from_arguments


def test_the_bench_file_reaches_the_emulator_as_an_absolute_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    options = options_from_arguments(
        build_parser().parse_args(
            ["--plant", "hardware", "--bench-file", "bench.yaml", "--scenario", "case1"]
        )
    )
    assert options.bench_file == str(tmp_path / "bench.yaml")
    emulator = next(spec for spec in build_graph(options) if spec.name == EMULATOR_NODE)
    assert dict(emulator.parameters)["bench-file"] == str(tmp_path / "bench.yaml")
    from smm_bench_emulator.cli import build_parser as emulator_parser
    from smm_bench_emulator.cli import from_ros_arguments

    parsed = emulator_parser().parse_args(from_ros_arguments(list(emulator.ros_arguments())))
    assert parsed.bench_file == str(tmp_path / "bench.yaml") and parsed.disturbance == "none"
    assert options_from_arguments(build_parser().parse_args(arguments_from_options(options))) == options


@pytest.mark.parametrize(
    "kwargs", [{"plant": "sim"}, {"plant": "hardware", "board": "192.168.1.20:50101"}, {"plant": "hardware"}]
)
def test_a_bench_file_without_an_emulator_or_empty_is_refused(kwargs: dict[str, str]) -> None:
    bench_file = "" if len(kwargs) == 1 and kwargs["plant"] == "hardware" else "bench.yaml"
    with pytest.raises(ValueError, match="bench_file"):
        GraphOptions(bench_file=bench_file, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("clock_mode", ["lockstep", "realtime"])
def test_on_the_canopen_link_the_bridge_states_the_supply_of_the_bench_the_emulator_runs(
    tmp_path: Path, clock_mode: str
) -> None:
    bench = tmp_path / "bench.yaml"
    bench.write_text("supply_pressure: 7.5\n")
    options = options_from_arguments(
        build_parser().parse_args(
            [
                "--plant",
                "hardware",
                "--link",
                "canopen",
                "--clock-mode",
                clock_mode,
                "--bench-file",
                str(bench),
            ]
        )
    )
    specs = build_graph(options)
    emulator = next(spec for spec in specs if spec.name == EMULATOR_NODE)
    bridge = next(spec for spec in specs if spec.name in (HW_NODE, DIRECT_LOOP))
    from smm_bench_emulator.cli import build_parser as emulator_parser
    from smm_bench_emulator.cli import config_from_args, from_ros_arguments

    parsed = emulator_parser().parse_args(from_ros_arguments(list(emulator.ros_arguments())))
    assert parsed.link == "canopen" and config_from_args(parsed).board.supply_pressure == 7.5
    assert dict(bridge.parameters)["canopen.supply_bar"] == 7.5  # no node sends it: the bench's, stated
    default = build_graph(GraphOptions(plant="hardware", link="canopen", clock_mode=clock_mode))
    bridge = next(spec for spec in default if spec.name in (HW_NODE, DIRECT_LOOP))
    assert dict(bridge.parameters)["canopen.supply_bar"] == default_bench().supply_pressure


def test_a_real_canopen_bench_gets_no_stated_supply_from_smm_launch() -> None:
    options = GraphOptions(plant="hardware", link="canopen", board="external")
    specs = build_graph(options)
    bridge = next(spec for spec in specs if spec.name in (HW_NODE, DIRECT_LOOP))
    assert all(spec.name != EMULATOR_NODE for spec in specs)
    assert "canopen.supply_bar" not in dict(bridge.parameters)  # the user's parameter file states it
