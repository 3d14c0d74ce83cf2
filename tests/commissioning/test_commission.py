"""probe -> jog -> identify -> tune -> verify on drawn emulated benches, through the commands, lockstep: each
step's findings against the bench's truths (issue 45's tolerances), no joint at its stop, verify's case 1
against the same run on the truths, and commissioned.yaml through the checks smm-launch and the nodes make."""

from __future__ import annotations

import argparse
import io
import json
import shutil
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from drawn_benches import bridge_of, draw_bench, truth_parameters, write_bench
from lockstep_case1 import SETTLED, case1, rms
from smm_analysis.scenarios import get_scenario
from smm_analysis.sweep.spec import build_settings
from smm_bench_emulator.bench_file import load_bench_file
from smm_bench_emulator.board import BoardConfig
from smm_bringup.graph import build_graph
from smm_bringup.graph_options import GraphOptions
from smm_commissioning.commands import EXIT_NOT_READY
from smm_commissioning.emulated import LockstepDevice
from smm_commissioning.host import BenchHost
from smm_commissioning.identify import OPEN_MARGIN
from smm_commissioning.steps import COMMISSIONED, passed_steps
from smm_commissioning.verify import VerifyConfig, run_verify, settings_of
from smm_hw_bridge.protocol import CODE_MAX
from smm_node_runtime.parameter_files import ParameterFileError, load_parameter_file

from smm_commissioning import cli

SEEDS = [2, 7, 12]
"""Drawn benches: beta's valve reversed on both, alpha's encoder counting down on 2, beta's on 7
(tests/drawn_benches.py); verify missed 1.2x of the truths on both with jog's blend of 5 codes (beta 1.28x on
2 at an earlier commit, on 7 at 7e00376; docs/COMMISSIONING.md), and 7's null bias is the one identify finds
the least well (1.42 codes). 12's beta valve opens at code 0 (null bias past its overlap): jog takes beta
first."""
STEPS = ("probe", "jog", "identify", "tune", "verify")


@dataclass
class Commissioned:
    """One bench commissioned through the commands."""

    seed: int
    bench: BoardConfig
    bench_file: Path
    out: Path
    codes: dict[str, int] = field(default_factory=dict)
    devices: list[LockstepDevice] = field(default_factory=list)

    @property
    def state(self) -> dict[str, Any]:
        return dict(json.loads((self.out / "state.json").read_text()))


def _commission(root: Path, seed: int) -> Commissioned:
    bench_file = write_bench(root / "bench.yaml", seed)
    done = Commissioned(seed, draw_bench(seed), bench_file, root / "out")

    def opener(arguments: argparse.Namespace) -> LockstepDevice:
        device = LockstepDevice(load_bench_file(arguments.bench_file))
        device.open()
        done.devices.append(device)
        return device

    common = ("--out", str(done.out), "--bench-file", str(bench_file))
    for step in STEPS:
        argv = ("tune", "--out", str(done.out)) if step == "tune" else (step, *common)
        if step not in ("probe", "tune"):
            argv = (*argv, "--confirm-motion")
        arguments = cli.parser().parse_args(argv)
        command = getattr(cli, f"{step}_command")
        err = io.StringIO()
        if step == "tune":
            done.codes[step] = command(arguments, io.StringIO(), err)
        else:
            done.codes[step] = command(arguments, io.StringIO(), err, opener=opener)
        assert done.codes[step] == 0, f"{step}: {err.getvalue()}"
    return done


@pytest.fixture(scope="module", params=SEEDS)
def commissioned(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Commissioned:
    return _commission(tmp_path_factory.mktemp(f"seed{request.param}"), request.param)


def test_every_step_passes_keeps_its_record_and_one_report_holds_them(commissioned: Commissioned) -> None:
    out = commissioned.out
    assert commissioned.codes == dict.fromkeys(STEPS, 0)
    report = (out / "REPORT.md").read_text()
    assert "Steps passed: probe, jog, identify, tune, verify." in report
    for heading in ("## probe: passed", "## jog: passed", "## identify: passed", "## tune: passed"):
        assert heading in report
    assert "## verify: READY" in report
    for record in ("probe", "jog", "identify", "identify_edges", "verify"):
        assert (out / f"{record}_record.npz").is_file()
    assert (out / "identify_bag").is_dir() and (out / "tune" / "runs.parquet").is_file()


def test_the_valves_and_encoders_are_found_within_the_tolerances(commissioned: Commissioned) -> None:
    bench, state = commissioned.bench, commissioned.state
    found = state["identify"]["parameters"]
    for j in range(2):
        assert found["bridge.encoder.direction"][j] == bench.direction[j]
        assert found["bridge.valve.polarity"][j] == bench.valve_polarity[j]
        overlap = found["bridge.valve.deadband"][j] - OPEN_MARGIN  # the edges' half distance
        assert abs(overlap / bench.valve_deadband[j] - 1.0) < 0.15
        assert abs(found["bridge.valve.null_bias"][j] - bench.valve_null_bias[j]) < 50.0
        nominal = CODE_MAX / bench.full_scale_torque[j]
        assert abs(nominal / found["bridge.valve.gain"][j] / bench.valve_gain_positive[j] - 1.0) < 0.05
        assert (
            abs(nominal / found["bridge.valve.gain_negative"][j] / bench.valve_gain_negative[j] - 1.0) < 0.05
        )


def test_identify_finds_the_overlap_to_the_codes_the_loop_needs(commissioned: Commissioned) -> None:
    """Far inside the issue's 50 codes: the loop needs the null within a code or two (docs)."""
    bench, state = commissioned.bench, commissioned.state
    found, jog = state["identify"]["parameters"], state["jog"]["parameters"]
    for j in range(2):
        error = abs(found["bridge.valve.null_bias"][j] - bench.valve_null_bias[j])
        print(
            f"seed {commissioned.seed} joint {j}: null bias off by {error:.2f} codes (jog's "
            f"{abs(jog['bridge.valve.null_bias'][j] - bench.valve_null_bias[j]):.2f})"
        )
        assert error < 2.0
        assert abs(found["bridge.valve.deadband"][j] - OPEN_MARGIN - bench.valve_deadband[j]) < 2.0


def test_the_model_is_found_within_the_tolerances(commissioned: Commissioned) -> None:
    truth, model = commissioned.bench.plant.params, commissioned.state["identify"]["model"]
    for name in ("I11", "I22", "I44", "I55", "mass_lever"):
        assert abs(model[f"model.{name}"] / getattr(truth, name) - 1.0) < 0.05, name
    for name in ("viscous_friction", "coulomb_friction", "torque_offset"):
        assert np.all(np.abs(np.array(model[f"model.{name}"]) - np.array(getattr(truth, name))) < 0.02), name


def test_no_joint_reaches_its_stop_in_any_step(commissioned: Commissioned) -> None:
    stops = commissioned.bench.plant.joint_limits
    assert len(commissioned.devices) >= 5  # probe, jog, the excitation, the edges, verify
    for device in commissioned.devices:
        assert all(device.peak[j] < stops[j] for j in range(2)), device.peak


def test_verify_tracks_case1_within_1_2x_of_the_same_run_on_the_truths(commissioned: Commissioned) -> None:
    """The same chosen gains and compensation settings; the bridge's truths and the plant's own model against
    the commissioned ones."""
    bench, state = commissioned.bench, commissioned.state
    config = VerifyConfig()
    settings = settings_of(state["tune"], config)
    device = LockstepDevice(bench)
    device.open()
    truths = run_verify(
        BenchHost(device),
        bridge_of(truth_parameters(bench)),
        replace(settings, model=bench.plant.params),
        config,
    )
    ratio = np.array(state["verify"]["bench_rms"]) / np.array(truths.bench)
    print(f"seed {commissioned.seed}: verify's case-1 RMS / the truths' = {ratio}")
    assert np.all(ratio < 1.2), ratio


def test_case1_on_identifys_bridge_parameters_tracks_as_on_the_benchs_truths(
    commissioned: Commissioned,
) -> None:
    """FPDESO on the nominal model: the bridge's parameters found against the truths, the same blend."""
    bench = commissioned.bench
    found = commissioned.state["identify"]["parameters"]
    commissioned_errors, peak = case1(bench, bridge_of(found))
    truth, _ = case1(bench, bridge_of(truth_parameters(bench)))
    ratio = rms(commissioned_errors[SETTLED:]) / rms(truth[SETTLED:])
    print(f"seed {commissioned.seed}: case-1 RMS on identify's parameters / on the truths = {ratio}")
    assert np.all(ratio < 1.2), ratio
    assert peak < bench.plant.joint_limits[0]


def test_case1_does_not_move_with_two_codes_of_null_bias_either_way() -> None:
    """identify's blend jumps the code over the overlap, so the spool is not held inside it while the torque
    passes through zero at speed: a null bias 2 codes off either way (identify's worst: 1.4) moves case 1's
    RMS by under 2 %. With the blend of 5 codes, +2 codes gave 0.71x on beta here (a lock spell less)."""
    bench = draw_bench(3)
    truths = truth_parameters(bench)
    base = rms(case1(bench, bridge_of(truths))[0][SETTLED:])
    for shift in (-2.0, 2.0):
        null = [float(b) + shift for b in bench.valve_null_bias]
        errors, _ = case1(bench, bridge_of({**truths, "bridge.valve.null_bias": null}))
        ratio = rms(errors[SETTLED:]) / base
        print(f"null bias {shift:+g} codes: case-1 RMS / the truths' = {ratio}")
        assert np.all(np.abs(ratio - 1.0) < 0.02), (shift, ratio)


def test_commissioned_yaml_passes_the_checks_of_smm_launch_and_of_the_nodes(
    commissioned: Commissioned, tmp_path: Path
) -> None:
    path = commissioned.out / COMMISSIONED
    options = GraphOptions(
        plant="hardware", bench_file=str(commissioned.bench_file), scenario="case1", params_files=(str(path),)
    )
    assert build_graph(options)  # every node's names checked (unknown names refused)
    bridge = load_parameter_file(path, "/smm/hw_bridge_node")
    assert bridge_of(bridge).valve.null_bias == tuple(
        commissioned.state["identify"]["parameters"]["bridge.valve.null_bias"]
    )
    controller = load_parameter_file(path, "/smm/controller_node")
    assert controller["algorithm"] == "fpdeso"
    built = build_settings("fpdeso", get_scenario("case1"), controller, {}, "commissioned.yaml")
    assert pytest.approx(commissioned.state["identify"]["model"]["model.I11"]) == built.model.I11
    document = yaml.safe_load(path.read_text())
    document["/**/hw_bridge_node"]["ros__parameters"]["bridge"]["valve"]["nul_bias"] = [0.0, 0.0]
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(yaml.safe_dump(document))
    with pytest.raises(ParameterFileError, match="nul_bias"):
        build_graph(replace(options, params_files=(str(wrong),)))


def test_tune_chooses_gains_no_worse_than_the_papers_in_the_worst_draw(commissioned: Commissioned) -> None:
    rows = {
        line.split("|")[1].split()[0]: [float(cell) for cell in line.split("|")[4:6]]
        for line in (commissioned.out / "tune.md").read_text().splitlines()
        if line.startswith(("| paper", "| chosen"))
    }
    assert rows["chosen"][0] <= rows["paper"][0] and rows["chosen"][1] <= rows["paper"][1]
    assert commissioned.state["tune"]["sections"]["/**/controller_node"]["algorithm"] == "fpdeso"


def test_a_bench_not_ready_gets_no_commissioned_yaml(commissioned: Commissioned, tmp_path: Path) -> None:
    """verify again with no margin over the model: the bench tracks worse on a joint, so not ready."""
    out = tmp_path / "out"
    shutil.copytree(commissioned.out, out)
    assert (out / COMMISSIONED).is_file()
    arguments = cli.parser().parse_args(
        [
            "verify",
            "--confirm-motion",
            "--ready-factor",
            "1.0",
            "--out",
            str(out),
            "--bench-file",
            str(commissioned.bench_file),
        ]
    )
    err = io.StringIO()
    assert cli.verify_command(arguments, io.StringIO(), err) == EXIT_NOT_READY
    assert not (out / COMMISSIONED).exists()
    assert passed_steps(out) == ["probe", "jog", "identify", "tune"]
    assert "## verify: NOT READY" in (out / "REPORT.md").read_text()
