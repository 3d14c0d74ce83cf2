"""smm-launch --bench-file: passed to the emulator, refused where there is no emulator."""

from __future__ import annotations

from pathlib import Path

import pytest
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import EMULATOR_NODE
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


def test_a_bench_file_on_the_canopen_link_is_refused() -> None:
    with pytest.raises(ValueError, match="bench_file is an option of plant 'hardware' with the frame link"):
        GraphOptions(plant="hardware", link="canopen", bench_file="bench.yaml")
