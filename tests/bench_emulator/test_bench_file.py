"""The bench description file: schema, defaults, refusals, the emulator's --bench-file and docs/BENCH.md."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from smm_bench_emulator.bench_file import (
    BenchFileError,
    bench_from_document,
    bench_table,
    default_bench,
    load_bench_file,
)
from smm_bench_emulator.board import BoardConfig
from smm_bench_emulator.cli import bench, build_parser, main
from smm_sim.plant import PAPER_VALVE_RESPONSE_TIMES, PlantConfig, valve_time_constants_from_response_times

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "src" / "smm_bench_emulator" / "config" / "bench_reversed.yaml"


def test_docs_list_every_field_of_the_bench_with_its_default() -> None:
    text = (ROOT / "docs" / "BENCH.md").read_text(encoding="utf-8")
    match = re.search(r"<!-- bench fields: [^>]*-->\n(.*?)<!-- end of bench fields -->", text, re.S)
    assert match is not None
    assert match.group(1) == bench_table()
    assert "`valve_null_bias`" in bench_table() and "`plant.params.I11`" in bench_table()


def test_without_a_file_the_emulator_runs_the_bench_it_always_ran() -> None:
    lag = valve_time_constants_from_response_times(*PAPER_VALVE_RESPONSE_TIMES)
    before = BoardConfig(
        plant=PlantConfig(encoder_counts_per_rev=1 << 20, valve_time_constants=lag, control_period=1e-3),
        full_scale_torque=(10.0, 10.0),
        seed=0,
    )
    assert default_bench() == before == bench(build_parser().parse_args([]))
    assert bench_from_document(None) == before  # an empty file: every default


def test_the_example_file_describes_the_acceptance_bench() -> None:
    config = load_bench_file(EXAMPLE)
    assert config.valve_polarity == config.direction == (-1, -1)
    assert config.valve_null_bias == (200.0, 200.0) and config.valve_deadband == (800.0, 800.0)
    assert (config.valve_gain_positive, config.valve_gain_negative) == ((0.8, 0.8), (1.2, 1.2))
    assert config.plant == default_bench().plant


def test_plant_fields_take_the_simulator_parameters_names_nested() -> None:
    config = bench_from_document(
        {"plant": {"params": {"I11": 0.08}, "noise_std": [0.001, 0.002], "valve_time_constants": [0, 0]}}
    )
    assert config.plant.params.I11 == 0.08 and config.plant.noise_std == (0.001, 0.002)
    assert config.plant.valve_time_constants is None  # (0, 0): no lag, as for smm_sim_node


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ({"valve_dedband": [800, 800]}, "unknown field 'valve_dedband'; did you mean 'valve_deadband'"),
        ({"plant": {"noise": [0, 0]}}, "did you mean 'plant.noise_std'"),
        ({"plant": {"initial_position": [0.1, 0.0]}}, "starts at rest at q = 0"),
        ({"valve_polarity": [0, 1]}, "valve_polarity must be"),
        ({"valve_null_bias": [200.0]}, "valve_null_bias must have 2 values"),
        ({"counter_bits": 16.5}, "counter_bits must be an integer"),
        ({"plant": {"inertia_scale": -1.0}}, "inertia_scale must be"),
        ([1, 2], "must map field names to values"),
    ],
)
def test_bad_descriptions_are_refused_naming_the_field(document: object, message: str) -> None:
    with pytest.raises(BenchFileError, match=re.escape(message)):
        bench_from_document(document)


def test_unreadable_or_broken_files_are_refused(tmp_path: Path) -> None:
    with pytest.raises(BenchFileError, match="cannot read bench file"):
        load_bench_file(tmp_path / "missing.yaml")
    broken = tmp_path / "broken.yaml"
    broken.write_text("valve_polarity: [1, \n", encoding="utf-8")
    with pytest.raises(BenchFileError, match="not valid YAML"):
        load_bench_file(broken)


def test_options_replace_the_fields_they_name_and_leave_the_rest_to_the_file() -> None:
    args = build_parser().parse_args(
        ["--bench-file", str(EXAMPLE), "--noise-std", "0.001", "--seed", "7", "--no-valve-lag"]
    )
    config = bench(args)
    assert config.plant.noise_std == (0.001, 0.001) and config.plant.seed == config.seed == 7
    assert config.plant.valve_time_constants is None
    assert config.valve_polarity == (-1, -1) and config.valve_deadband == (800.0, 800.0)  # from the file


def test_the_emulator_exits_2_on_a_bad_bench_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bench.yaml"
    bad.write_text("valve_gain_postive: [0.8, 0.8]\n", encoding="utf-8")
    assert main(["--bench-file", str(bad)]) == 2
    assert "did you mean 'valve_gain_positive'" in capsys.readouterr().err
