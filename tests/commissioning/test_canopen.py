"""smm-commission on the CANopen link, through the commands: probe -> jog -> identify -> tune -> verify on a
drawn bench emulated as CiA 408 valves and CiA 406 encoders (udp_multicast on loopback, in this process,
lockstep), each finding against the bench's truths in the valves' units (+-16384 = 100 % spool); probe's
faults on the bus named with the node, nothing enabled; Ctrl-C leaves every valve DISABLED; a real bus
(``--board external``, real time) probed; the options that do not fit the link refused."""

from __future__ import annotations

import argparse
import io
import itertools
import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from drawn_benches import bridge_of, draw_bench, truth_parameters, write_bench
from smm_bench_emulator.board import BoardConfig
from smm_bench_emulator.canopen_bench import CanBench, CanBenchConfig, eds_path
from smm_commissioning.commands import EXIT_FAULT, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE
from smm_commissioning.emulated import CanopenLockstepDevice
from smm_commissioning.host import BenchHost, in_link_units, valve_units
from smm_commissioning.link import canopen_settings, emulated_canopen, open_bench
from smm_commissioning.steps import COMMISSIONED, passed_steps
from smm_commissioning.verify import VerifyConfig, run_verify, settings_of
from smm_hw_bridge.can_multicast import loopback_multicast_bus
from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.canopen_configure import ConfigureError, check_bridge
from smm_hw_bridge.cia408 import SPOOL_FULL_SCALE, ValveState
from smm_hw_bridge.device import ValveCommand
from smm_hw_bridge.protocol import CODE_MAX
from smm_node_runtime.parameter_files import load_parameter_file

from smm_commissioning import cli

SEED = 0
"""The drawn bench (tests/drawn_benches.py): beta's valve reversed and its encoder counting down."""
PORT = 43150
"""This module's UDP port of the loopback multicast group (its own: no other test's bus on it)."""
SPOOL = SPOOL_FULL_SCALE / CODE_MAX
"""Spool units per D/A code of the frame board: the emulated valve takes a spool setpoint s as the code
s / SPOOL."""
STEPS = ("probe", "jog", "identify", "tune", "verify")
INERTIAS = ("I11", "I22", "I44", "I55", "mass_lever")
OFFSETS = ("viscous_friction", "coulomb_friction", "torque_offset")
Opener = Callable[[argparse.Namespace], CanopenLockstepDevice]
chain = pytest.mark.xdist_group("canopen_commissioning")
"""The tests of the commissioned bench: on one worker, its module fixture built once."""


def params_file(path: Path, **canopen: Any) -> Path:
    """A bridge parameter file with ``canopen.*`` (this module's port unless given)."""
    values = {"port": PORT, **canopen}
    path.write_text(yaml.safe_dump({"/**/hw_bridge_node": {"ros__parameters": {"canopen": values}}}))
    return path


def run(*argv: str, opener: Opener | None = None) -> tuple[int, str, str]:
    """The step's exit code, stdout and stderr."""
    arguments = cli.parser().parse_args(argv)
    command = getattr(cli, f"{arguments.step}_command")
    out, err = io.StringIO(), io.StringIO()
    code = command(arguments, out, err) if opener is None else command(arguments, out, err, opener=opener)
    return code, out.getvalue(), err.getvalue()


def recording(devices: list[CanopenLockstepDevice], *faults: Callable[[CanBench], None]) -> Opener:
    """The command's own opener; each device kept, each fault injected into its bench once it is open."""

    def opener(arguments: argparse.Namespace) -> CanopenLockstepDevice:
        device = open_bench(arguments)
        assert isinstance(device, CanopenLockstepDevice) and device.bench is not None
        for fault in faults:
            fault(device.bench)
        devices.append(device)
        return device

    return opener


def spool_truths(bench: BoardConfig) -> dict[str, object]:
    """The bridge parameters that carry the bench's truths, in the valves' units on this link."""
    truths = truth_parameters(bench)
    in_spool = ("null_bias", "deadband", "gain", "gain_negative")
    for name in in_spool:
        values = truths[f"bridge.valve.{name}"]
        assert isinstance(values, list)
        truths[f"bridge.valve.{name}"] = [value * SPOOL for value in values]
    return {**truths, **valve_units("canopen")}


@dataclass
class Commissioned:
    """The drawn bench commissioned on CANopen through the commands (each step exited 0)."""

    bench: BoardConfig
    out: Path
    params: Path
    devices: list[CanopenLockstepDevice]

    @property
    def state(self) -> dict[str, Any]:
        return dict(json.loads((self.out / "state.json").read_text()))


@pytest.fixture(scope="module")
def commissioned(tmp_path_factory: pytest.TempPathFactory) -> Commissioned:
    root = tmp_path_factory.mktemp("canopen")
    done = Commissioned(draw_bench(SEED), root / "out", params_file(root / "can.yaml"), [])
    bench_file = write_bench(root / "bench.yaml", SEED)
    link = ("--link", "canopen", "--params-file", str(done.params), "--bench-file", str(bench_file))
    for step in STEPS:
        argv: tuple[str, ...] = ("tune", "--out", str(done.out))
        if step != "tune":
            argv = (step, "--out", str(done.out), *link)
        if step not in ("probe", "tune"):
            argv = (*argv, "--confirm-motion")
        code, _, err = run(*argv, opener=None if step == "tune" else recording(done.devices))
        assert code == EXIT_OK, f"{step}: {err}"
    return done


@chain
def test_every_step_passes_on_the_canopen_bench_and_probe_names_each_node(commissioned: Commissioned) -> None:
    report = (commissioned.out / "REPORT.md").read_text()
    assert "Steps passed: probe, jog, identify, tune, verify." in report and "## verify: READY" in report
    for name, profile in (
        ("valve alpha (node 1)", "0x00000198 (CiA 408) | OPERATIONAL | DISABLED"),
        ("valve beta (node 2)", "0x00000198 (CiA 408) | OPERATIONAL | DISABLED"),
        ("encoder alpha (node 11)", "0x00020196 (CiA 406) | OPERATIONAL | - |"),
        ("encoder beta (node 12)", "0x00020196 (CiA 406) | OPERATIONAL | - |"),
    ):
        assert f"| {name} | {profile}" in report
    assert "| supply (bar, stated: canopen.supply_bar) | 10.00 |" in report
    assert len(commissioned.devices) >= 5  # probe, jog, the excitation, the edges, verify: all on CANopen


@chain
def test_the_valves_and_encoders_are_found_within_the_tolerances_in_spool_units(
    commissioned: Commissioned,
) -> None:
    bench, found = commissioned.bench, commissioned.state["identify"]["parameters"]
    for j in range(2):
        assert found["bridge.encoder.direction"][j] == bench.direction[j]
        assert found["bridge.valve.polarity"][j] == bench.valve_polarity[j]
        deadband, null = found["bridge.valve.deadband"][j], found["bridge.valve.null_bias"][j]
        print(
            f"joint {j}: deadband {deadband} units (truth {bench.valve_deadband[j] * SPOOL:.1f}), null bias "
            f"{null} (truth {bench.valve_null_bias[j] * SPOOL:.1f})"
        )
        assert abs(deadband / (bench.valve_deadband[j] * SPOOL) - 1.0) < 0.15
        assert abs(null / SPOOL - bench.valve_null_bias[j]) < 50.0  # 50 codes of the D/A, 25 units
        nominal = SPOOL_FULL_SCALE / bench.full_scale_torque[j]  # units per N m at a gain of 1
        assert abs(nominal / found["bridge.valve.gain"][j] / bench.valve_gain_positive[j] - 1.0) < 0.05
        assert (
            abs(nominal / found["bridge.valve.gain_negative"][j] / bench.valve_gain_negative[j] - 1.0) < 0.05
        )
    assert found["bridge.valve.code_limit"] == [SPOOL_FULL_SCALE, SPOOL_FULL_SCALE]


@chain
def test_the_model_is_found_within_the_tolerances(commissioned: Commissioned) -> None:
    truth, model = commissioned.bench.plant.params, commissioned.state["identify"]["model"]
    relative = {name: model[f"model.{name}"] / getattr(truth, name) - 1.0 for name in INERTIAS}
    offsets = {name: np.subtract(model[f"model.{name}"], getattr(truth, name)).tolist() for name in OFFSETS}
    print(f"inertias and lever, relative error: {relative}; friction and offsets, N m: {offsets}")
    assert max(map(abs, relative.values())) < 0.05, relative
    assert np.max(np.abs(list(offsets.values()))) < 0.02, offsets


@chain
def test_no_joint_reaches_its_stop_in_any_step(commissioned: Commissioned) -> None:
    stops = commissioned.bench.plant.joint_limits
    for device in commissioned.devices:
        assert all(device.peak[j] < stops[j] for j in range(2)), device.peak


@chain
def test_verify_tracks_case1_within_1_2x_of_the_same_run_on_the_truths(commissioned: Commissioned) -> None:
    bench, state = commissioned.bench, commissioned.state
    config = VerifyConfig()
    device = CanopenLockstepDevice(bench, emulated_canopen(canopen_settings([commissioned.params]), bench))
    device.open()
    try:
        settings = replace(settings_of(state["tune"], config), model=bench.plant.params)
        truths = run_verify(BenchHost(device), bridge_of(spool_truths(bench)), settings, config)
    finally:
        device.close()
    ratio = np.array(state["verify"]["bench_rms"]) / np.array(truths.bench)
    print(f"verify's case-1 RMS {state['verify']['bench_rms']} / the truths' {truths.bench} = {ratio}")
    assert np.all(ratio < 1.2), ratio


@chain
def test_commissioned_yaml_fits_the_canopen_link(commissioned: Commissioned) -> None:
    """The valves' units come with it: the bridge's default code limit (32767) is refused on this link."""
    parameters = load_parameter_file(commissioned.out / COMMISSIONED, "/smm/hw_bridge_node")
    bridge = bridge_of(parameters)
    assert bridge.valve.code_limit == (SPOOL_FULL_SCALE, SPOOL_FULL_SCALE)
    check_bridge(CanopenConfig(valve_eds="v.eds", encoder_eds="e.eds"), bridge)
    with pytest.raises(ConfigureError, match="above the valves' full scale 16384"):
        check_bridge(CanopenConfig(valve_eds="v.eds", encoder_eds="e.eds"), bridge_of({}))


# ---- probe's faults on the bus ------------------------------------------------------------------------


@pytest.fixture
def probe_out(tmp_path: Path) -> Iterator[tuple[Path, tuple[str, ...]]]:
    """A drawn bench's file and the probe's common arguments (300 feedbacks)."""
    yield (
        tmp_path / "out",
        (
            "--out",
            str(tmp_path / "out"),
            "--link",
            "canopen",
            "--params-file",
            str(params_file(tmp_path / "can.yaml")),
            "--ticks",
            "300",
        ),
    )


def probed(
    tmp_path: Path, common: tuple[str, ...], *faults: Callable[[CanBench], None], **bench: Any
) -> tuple[int, str, str, CanopenLockstepDevice]:
    """probe on drawn bench 5 (with ``bench`` overrides) and ``faults``; asserts nothing was enabled."""
    devices: list[CanopenLockstepDevice] = []
    bench_file = write_bench(tmp_path / "bench.yaml", 5, **bench)
    code, out, err = run(
        "probe", *common, "--bench-file", str(bench_file), opener=recording(devices, *faults)
    )
    (device,) = devices
    assert device.bench is not None and device.bench.active_syncs == 0
    assert device.bench.valve_states() != (ValveState.ACTIVE, ValveState.ACTIVE)
    assert "enabled commands sent: none" in out
    return code, out, err, device


def test_a_healthy_canopen_bench_passes_probe(
    tmp_path: Path, probe_out: tuple[Path, tuple[str, ...]]
) -> None:
    code, out, err, device = probed(tmp_path, probe_out[1])
    assert code == EXIT_OK, err
    assert "| valve beta (node 2) | 0x00000198 (CiA 408) | OPERATIONAL | DISABLED |" in out
    assert device.bench is not None
    assert device.bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
    assert passed_steps(probe_out[0]) == ["probe"]


def test_low_supply_is_named_from_canopen_supply_bar(
    tmp_path: Path, probe_out: tuple[Path, tuple[str, ...]]
) -> None:
    code, _, err, _ = probed(tmp_path, probe_out[1], supply_pressure=3.0)
    assert code == EXIT_FAULT
    assert "FAULT: supply pressure 3.00 bar (canopen.supply_bar: no CANopen node sends it" in err
    code, _, err = run("jog", "--confirm-motion", *probe_out[1], "--bench-file", str(tmp_path / "bench.yaml"))
    assert code == 4 and "jog needs probe to have passed" in err


@pytest.mark.parametrize("joint", [0, 1])
def test_an_encoder_not_counting_is_named_with_its_node(
    tmp_path: Path, probe_out: tuple[Path, tuple[str, ...]], joint: int
) -> None:
    def freeze(bench: CanBench) -> None:
        counts = bench.board.counts
        frozen = counts()[joint]
        bench.board.counts = lambda: (frozen, counts()[1]) if joint == 0 else (counts()[0], frozen)

    code, _, err, _ = probed(tmp_path, probe_out[1], freeze)
    name = ("alpha", "beta")[joint]
    assert code == EXIT_FAULT
    assert f"FAULT: encoder {name} does not count" in err
    assert f"encoder {name} (node {11 + joint})'s node" in err
    assert err.count("FAULT:") == 1


@pytest.mark.parametrize("joint", [0, 1])
def test_a_stuck_pressure_actual_is_named_with_its_valve(
    tmp_path: Path, probe_out: tuple[Path, tuple[str, ...]], joint: int
) -> None:
    def stick(bench: CanBench) -> None:
        valve = bench.valves[joint]
        transmit = valve.transmit
        valve.transmit = lambda pressure: transmit(30.0)

    code, _, err, _ = probed(tmp_path, probe_out[1], stick)
    assert code == EXIT_FAULT
    assert (
        f"FAULT: valve {('alpha', 'beta')[joint]} (node {1 + joint}): pressure actual 0x6381:01 is stuck at "
        "30 units (0.30 bar) over 300 SYNCs" in err
    )
    assert err.count("FAULT:") == 1


def test_a_pressure_actual_at_its_rail_is_named(
    tmp_path: Path, probe_out: tuple[Path, tuple[str, ...]]
) -> None:
    def short(bench: CanBench) -> None:
        transmit = bench.valves[1].transmit
        bench.valves[1].transmit = lambda pressure: transmit(40000.0)  # clipped to the INT16 rail

    code, _, err, _ = probed(tmp_path, probe_out[1], short)
    assert code == EXIT_FAULT
    assert "FAULT: valve beta (node 2): pressure actual 0x6381:01 reads its rail (32767..32767 units)" in err


def test_a_valve_fault_is_named_with_its_node_and_emcy_code(
    tmp_path: Path, probe_out: tuple[Path, tuple[str, ...]]
) -> None:
    code, _, err, device = probed(tmp_path, probe_out[1], lambda bench: bench.valves[1].miss_deadline())
    assert code == EXIT_FAULT
    assert "FAULT: valve beta (node 2): EMCY 0x8250 (error register 0x11): clear its cause" in err
    assert "FAULT: valve beta (node 2): status word 0x0001 (FAULT_DISABLED)" in err
    assert device.bench is not None and device.bench.valve_states()[0] is ValveState.DISABLED


def test_a_missing_node_is_a_fault_named_with_the_node(
    tmp_path: Path, probe_out: tuple[Path, tuple[str, ...]]
) -> None:
    def opener(arguments: argparse.Namespace) -> CanopenLockstepDevice:
        bench = draw_bench(5)
        device = CanopenLockstepDevice(
            bench, emulated_canopen(canopen_settings(arguments.params_file), bench)
        )
        device.bench_config = replace(device.bench_config, encoder_node_ids=(11, 14))  # node 12 never answers
        device.open()
        return device

    code, _, err = run("probe", *probe_out[1], "--bench-file", "unused.yaml", opener=opener)
    assert code == EXIT_FAULT
    assert "encoder beta (node 12): no answer to reading 0x1000:00" in err
    assert "no answer to reading 0x1000:00" in (probe_out[0] / "REPORT.md").read_text()


def test_ctrl_c_during_the_jog_leaves_every_valve_disabled(
    tmp_path: Path, probe_out: tuple[Path, tuple[str, ...]]
) -> None:
    bench_file = write_bench(tmp_path / "bench.yaml", 5)
    common = (*probe_out[1], "--bench-file", str(bench_file))
    assert run("probe", *common)[0] == EXIT_OK
    devices: list[CanopenLockstepDevice] = []
    enabled = itertools.count(1)

    def opener(arguments: argparse.Namespace) -> CanopenLockstepDevice:
        device = recording(devices)(arguments)
        write = device.write

        def interrupting(command: ValveCommand) -> None:
            write(command)
            if command.enabled and next(enabled) == 300:
                raise KeyboardInterrupt

        device.write = interrupting
        return device

    code, _, err = run("jog", "--confirm-motion", *common, opener=opener)
    assert code == EXIT_INTERRUPTED and "interrupted; the valves are disabled" in err
    (device,) = devices
    assert device.bench is not None and device.bench.active_syncs > 0  # it had moved
    assert [valve.setpoint for valve in device.bench.valves] == [0, 0]  # the last setpoints: null
    assert device.bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
    assert passed_steps(probe_out[0]) == ["probe"]


def test_a_real_bus_is_probed_in_real_time(tmp_path: Path) -> None:
    """``--board external``: the master of the parameter file's nodes, SYNC on its own clock (a bench on
    the bus that this test starts, as a real one would be)."""
    port = PORT + 1
    bench = CanBench(CanBenchConfig(board=draw_bench(6)), loopback_multicast_bus("239.74.163.2", port))
    params = params_file(
        tmp_path / "bench.yaml",
        port=port,
        valve_eds=str(eds_path("valve_cia408.eds")),
        encoder_eds=str(eds_path("encoder_cia406.eds")),
        heartbeat_ms=1000,
        pdo_validity_ms=2000,
        receive_deadline_ms=2000,
    )
    try:
        code, out, err = run(
            "probe",
            *("--out", str(tmp_path / "out"), "--link", "canopen", "--board", "external"),
            *("--params-file", str(params), "--ticks", "300", "--timeout", "5"),
        )
    finally:
        bench.close()
    assert code == EXIT_OK, err
    assert "| encoder beta (node 12) | 0x00020196 (CiA 406) | OPERATIONAL | - |" in out
    assert bench.active_syncs == 0 and bench.syncs >= 300


# ---- what does not fit the link ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "extra, words",
    [
        (("--board", "127.0.0.1:50101"), "--link canopen takes --board external"),
        (("--bench-file", "b.yaml", "--params-file", "{bad}"), "unknown parameter(s) ['canopen.chanel']"),
        (("--bench-file", "b.yaml", "--params-file", "{ids}"), "node ids must differ"),
        (("--bench-file", "b.yaml", "--params-file", "{socketcan}"), "runs on udp_multicast or virtual"),
    ],
)
def test_options_that_do_not_fit_the_canopen_link_are_refused(
    tmp_path: Path, extra: tuple[str, ...], words: str
) -> None:
    files = {
        "{bad}": params_file(tmp_path / "bad.yaml", chanel="can0"),
        "{ids}": params_file(tmp_path / "ids.yaml", valve_node_ids=[1, 11]),
        "{socketcan}": params_file(tmp_path / "socketcan.yaml", interface="socketcan", channel="can0"),
    }
    files["b.yaml"] = write_bench(tmp_path / "b.yaml", 1)
    argv = [str(files[a]) if a in files else a for a in extra]
    code, _, err = run("probe", "--out", str(tmp_path / "out"), "--link", "canopen", *argv)
    assert code == EXIT_USAGE and words in err, err
    assert not (tmp_path / "out" / "state.json").exists()


def test_a_parameter_file_on_the_frame_link_is_refused(tmp_path: Path) -> None:
    bench = write_bench(tmp_path / "bench.yaml", 1)
    params = params_file(tmp_path / "can.yaml")
    code, _, err = run(
        "probe", "--out", str(tmp_path / "out"), "--bench-file", str(bench), "--params-file", str(params)
    )
    assert code == EXIT_USAGE and "only with --link canopen" in err


def test_the_jogs_steps_and_limits_are_the_frame_links_in_spool_units() -> None:
    assert in_link_units(150, "canopen") == 75 and in_link_units(150, "frame") == 150
    assert in_link_units(1, "canopen") == 1
    assert valve_units("canopen")["bridge.valve.code_limit"] == [16384, 16384]
    assert valve_units("canopen")["bridge.valve.rate_limit"] == [16384 / 0.002] * 2
    assert valve_units("frame") == {}
    assert canopen_settings([]).period_us == 1000
