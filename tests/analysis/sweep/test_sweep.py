"""smm-sweep: spec validation naming the field, resume, worker independence, re-run, outputs."""

from __future__ import annotations

import io
import re
import socket
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
import yaml
from smm_analysis.batch import INDEX_NAMES, scalar_indices
from smm_analysis.sweep.cli import main
from smm_analysis.sweep.command import EXIT_ERROR, EXIT_OK, SweepOptions, rerun, sweep
from smm_analysis.sweep.execute import SchedulerError, SweepFolderError, batches, finished_batches, run_sweep
from smm_analysis.sweep.results import pareto_mask
from smm_analysis.sweep.spec import SpecError, parse_spec

BASE: dict[str, Any] = {
    "name": "test",
    "controller": "fpdeso",
    "scenarios": ["step", "case2"],
    "duration": 0.06,
    "fixed": {"fpdeso.boundary_layer": [0.05, 0.05]},
    "gains": {
        "td.filter_factor": {"grid": [[0.001, 0.001], [0.002, 0.002]]},
        "fpdeso.fuzzy.kd0[1]": {"range": [80.0, 130.0]},
    },
    "sampling": {"method": "lhs", "count": 2, "seed": 3},
    "plant_draws": {
        "count": 2,
        "seed": 4,
        "parameters": {
            "inertia_scale": {"uniform": [0.8, 1.2], "relative": True},
            "seed": {"integers": [0, 999]},
        },
    },
    "objectives": ["case2.RMS_beta", "case2.eps_u_beta", "step.overshoot_beta"],
    "constraints": {"step.overshoot_beta": {"<": 0.05}, "case2.RMS_beta": {"<": "fpd"}},
    "batch_size": 3,
}


def _spec(**changes: Any) -> dict[str, Any]:
    spec = {key: value for key, value in BASE.items() if changes.get(key, "") is not None}
    spec.update({key: value for key, value in changes.items() if value is not None})
    return spec


def _write(tmp_path: Path, spec: dict[str, Any]) -> Path:
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"gains": {"fpdeso.fuzzy.bogus": {"grid": [1.0]}}},
            r"gains\.fpdeso\.fuzzy\.bogus: unknown parameter",
        ),
        (
            {"gains": {"fpd.fuzzy.kd0": {"grid": [[1.0, 1.0]]}}},
            r"gains\.fpd\.fuzzy\.kd0: unknown parameter .* runs fpdeso",
        ),
        ({"fixed": {"td.nothing": 1.0}}, r"fixed\.td\.nothing: unknown parameter"),
        ({"plant": {"params.bogus": 1.0}}, r"plant\.params\.bogus: unknown parameter"),
        (
            {"plant_draws": {"count": 2, "parameters": {"params.I99": {"uniform": [0.1, 0.2]}}}},
            r"plant_draws\.parameters\.params\.I99: unknown parameter",
        ),
        ({"plant": {"control_period": 0.002}}, r"plant\.control_period: control_period cannot be swept"),
        (
            {"gains": {"fpdeso.fuzzy.kp0[0]": {"range": [-5.0, 10.0]}}},
            r"gains\.fpdeso\.fuzzy\.kp0\[0\]\.range end -5\.0: kp0",
        ),
        (
            {"sampling": None, "gains": {"fleso.w0": {"grid": [[20.0, 28.0], [0.0, 28.0]]}}},
            r"gains\.fleso\.w0\.grid value \[0\.0, 28\.0\]: w0",
        ),
        (
            {"gains": {"td.filter_factor": {"grid": []}}},
            r"gains\.td\.filter_factor\.grid must be a non-empty list",
        ),
        ({"gains": {"td.speed": {"range": [5.0, 1.0]}}}, r"gains\.td\.speed\.range must have low < high"),
        ({"plant": {"noise_std": [-0.1, 0.0]}}, r"noise_std"),
        ({"objectives": ["case2.bogus"]}, r"objectives\[0\]: unknown index 'bogus'"),
        ({"objectives": ["RMS_beta"]}, r"objectives\[0\]: 'RMS_beta' needs its scenario"),
        ({"scenarios": ["case9"]}, r"scenarios: unknown scenario 'case9'"),
        ({"controller": "lqr"}, r"controller must be one of"),
        ({"constraints": {"case2.RMS_beta": {"<<": 1.0}}}, r"constraints\.case2\.RMS_beta: unknown operator"),
        ({"bogus": 1}, r"unknown spec keys \['bogus'\]"),
        (
            {"fpdeso.fuzzy.kd0[2]": None, "gains": {"fpdeso.fuzzy.kd0[2]": {"grid": [1.0]}}},
            r"is not a parameter name",
        ),
    ],
)
def test_a_bad_spec_is_refused_naming_the_field(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(SpecError, match=message):
        parse_spec(_spec(**changes))


@pytest.mark.parametrize(
    ("changes", "closest"),
    [
        ({"gains": {"td.filter_factr": {"grid": [[0.001, 0.001]]}}}, "td.filter_factor"),
        ({"gains": {"fpdeso.fuzzy.kd00[1]": {"range": [80.0, 130.0]}}}, "fpdeso.fuzzy.kd0"),
        ({"fixed": {"fleso.w": [20.0, 20.0]}}, "fleso.w0"),
        ({"plant": {"inertia_scal": 1.1}}, "inertia_scale"),
        ({"plant_draws": {"count": 2, "parameters": {"noise_st": {"uniform": [0.0, 0.1]}}}}, "noise_std"),
    ],
)
def test_an_unknown_name_is_refused_with_the_closest_known_one(changes: dict[str, Any], closest: str) -> None:
    with pytest.raises(SpecError, match=rf"unknown parameter .*; did you mean '{re.escape(closest)}'\?$"):
        parse_spec(_spec(**changes))


def test_the_cli_reports_a_bad_spec_and_returns_2(tmp_path: Path) -> None:
    stderr = io.StringIO()
    path = _write(tmp_path, _spec(gains={"fpdeso.fuzzy.bogus": {"grid": [1.0]}}))
    code = sweep(SweepOptions(path, tmp_path / "out", 1, None, None), io.StringIO(), stderr)
    assert code == EXIT_ERROR
    assert "gains.fpdeso.fuzzy.bogus: unknown parameter" in stderr.getvalue()


def test_runs_are_numbered_and_batched_per_scenario() -> None:
    spec = parse_spec(_spec())
    assert spec.run_count == 4 * 2 * 2
    assert len(spec.gain_sets) == 4
    found = sorted(run for batch in batches(spec) for run in batch.run_ids)
    assert found == list(range(spec.run_count))
    for batch in batches(spec):
        assert len({spec.locate(run)[2] for run in batch.run_ids}) == 1
    gain_set, draw, scenario = spec.locate(13)
    assert (gain_set * 2 + draw) * 2 + scenario == 13
    settings = spec.settings(13)
    assert settings.law.fuzzy.kd0[1] == spec.gain_sets[gain_set]["fpdeso.fuzzy.kd0[1]"]
    assert settings.plant.seed == spec.plant_draws[draw]["seed"]
    assert settings.plant.inertia_scale == spec.plant_draws[draw]["inertia_scale"]


def _runs(out: Path) -> np.ndarray:
    table = pq.read_table(out / "runs.parquet")
    return np.stack([table.column(name).to_numpy() for name in ("run_id", *INDEX_NAMES)], axis=-1)


def test_a_sweep_writes_every_output_and_does_not_depend_on_workers_or_batch_size(tmp_path: Path) -> None:
    one = tmp_path / "one"
    two = tmp_path / "two"
    path = _write(tmp_path, _spec())
    assert sweep(SweepOptions(path, one, 1, None, None), io.StringIO(), io.StringIO()) == EXIT_OK
    other = _write(tmp_path / "b", _spec(batch_size=5)) if (tmp_path / "b").mkdir() is None else path
    assert sweep(SweepOptions(other, two, 2, None, None), io.StringIO(), io.StringIO()) == EXIT_OK
    assert np.array_equal(_runs(one), _runs(two), equal_nan=True)
    for name in (
        "runs.parquet",
        "gain_sets.parquet",
        "pareto.png",
        "sensitivity.png",
        "report.md",
        "chosen.yaml",
    ):
        assert (one / name).is_file(), name
    runs = pq.read_table(one / "runs.parquet")
    assert runs.num_rows == 16
    assert {
        "gain.td.filter_factor[0]",
        "gain.fpdeso.fuzzy.kd0[1]",
        "plant.inertia_scale",
        "plant.seed",
        "seed",
    } <= set(runs.column_names)
    spec = parse_spec(_spec())
    row = 5
    expected = scalar_indices(spec.settings(row))
    assert runs.column("RMS_alpha")[row].as_py() == pytest.approx(expected["RMS_alpha"], rel=1e-9)
    report = (one / "report.md").read_text(encoding="utf-8")
    assert "## Pareto front" in report and "P95" in report and "step.overshoot_beta < 0.05" in report


def test_the_chosen_parameters_file_holds_the_chosen_gains(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert (
        sweep(SweepOptions(_write(tmp_path, _spec()), out, 1, None, None), io.StringIO(), io.StringIO()) == 0
    )
    document = yaml.safe_load((out / "chosen.yaml").read_text(encoding="utf-8"))
    controller = document["/**/controller_node"]["ros__parameters"]
    chain = document["/**"]["ros__parameters"]
    gain_sets = pq.read_table(out / "gain_sets.parquet")
    chosen = int(
        next(
            line for line in (out / "report.md").read_text().splitlines() if line.startswith("Gain set ")
        ).split()[2]
    )
    assert controller["algorithm"] == "fpdeso"
    assert (
        controller["fpdeso"]["fuzzy"]["kd0"][1]
        == gain_sets.column("gain.fpdeso.fuzzy.kd0[1]")[chosen].as_py()
    )
    assert chain["td"]["filter_factor"][0] == gain_sets.column("gain.td.filter_factor[0]")[chosen].as_py()
    assert controller["fpdeso"]["boundary_layer"] == [0.05, 0.05]


def test_an_interrupted_sweep_resumes_from_its_parts(tmp_path: Path) -> None:
    out = tmp_path / "out"
    spec = parse_spec(_spec())
    assert run_sweep(spec, out) == len(batches(spec))
    first = _parts(out)
    (out / "parts" / "batch-00002.parquet").unlink()
    (out / "parts" / "batch-00004.parquet").unlink()
    assert run_sweep(spec, out) == 2
    assert _parts(out) == first
    assert run_sweep(spec, out) == 0


def _parts(out: Path) -> dict[str, bytes]:
    """Each part's values as bytes (NaN compares equal to NaN this way)."""
    return {
        path.name: np.stack(
            [column.to_numpy().astype(float) for column in pq.read_table(path).columns]
        ).tobytes()
        for path in sorted((out / "parts").glob("*.parquet"))
    }


def test_a_folder_of_another_sweep_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "out"
    run_sweep(parse_spec(_spec(duration=0.03)), out)
    with pytest.raises(SweepFolderError, match="another sweep spec"):
        run_sweep(parse_spec(_spec()), out)


def _closed_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def test_an_unreachable_scheduler_is_named_and_finished_batches_are_kept(tmp_path: Path) -> None:
    out = tmp_path / "out"
    spec = parse_spec(_spec())
    run_sweep(spec, out)
    (out / "parts" / "batch-00001.parquet").unlink()
    kept = finished_batches(out)
    address = f"tcp://127.0.0.1:{_closed_port()}"
    with pytest.raises(SchedulerError, match=f"cannot reach the Dask scheduler at {address}"):
        run_sweep(spec, out, scheduler=address)
    assert finished_batches(out) == kept
    stderr = io.StringIO()
    code = sweep(SweepOptions(_write(tmp_path, _spec()), out, 1, address, None), io.StringIO(), stderr)
    assert code == EXIT_ERROR
    assert address in stderr.getvalue()


def test_rerun_gives_the_sweeps_indices_with_the_scalar_loop(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    path = _write(tmp_path, _spec())
    assert main([str(path), "--out", str(out), "--workers", "1"]) == 0
    assert main([str(path), "--out", str(out), "--rerun", "9"]) == 0
    printed = capsys.readouterr().out
    assert "DIFFERS" not in printed and "RMS_alpha" in printed
    assert (out / "rerun-9.yaml").is_file()
    assert rerun(SweepOptions(path, out, 1, None, 999), io.StringIO(), io.StringIO()) == EXIT_ERROR


def test_pareto_front_keeps_exactly_the_non_dominated_points() -> None:
    points = np.array([[1.0, 5.0], [2.0, 2.0], [3.0, 3.0], [5.0, 1.0], [np.inf, 0.0], [2.0, 2.0]])
    assert pareto_mask(points).tolist() == [True, True, False, True, False, True]
