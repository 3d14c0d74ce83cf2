"""smm-commission's probe and jog through the command layer, on bench files: the order of the steps, the
state and reports in --out, the parameter file, exit codes; Ctrl-C and failures leave the valves disabled."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
import yaml
from drawn_benches import draw_bench, write_bench
from smm_commissioning.commands import EXIT_FAULT, EXIT_INTERRUPTED, EXIT_OK, EXIT_ORDER, EXIT_USAGE
from smm_commissioning.emulated import LockstepDevice
from smm_commissioning.steps import passed_steps
from smm_hw_bridge.device import ValveCommand
from smm_hw_bridge.protocol import CODE_MAX
from smm_node_runtime.parameter_files import load_parameter_file

from smm_commissioning import cli


def run(*argv: str) -> tuple[int, str]:
    err = io.StringIO()
    arguments = cli.parser().parse_args(argv)
    command = getattr(cli, f"{arguments.step}_command")
    return command(arguments, io.StringIO(), err), err.getvalue()


def test_probe_then_jog_writes_the_bridges_truths(tmp_path: Path) -> None:
    seed = 1
    bench = write_bench(tmp_path / "bench.yaml", seed)
    truth = draw_bench(seed)
    out = tmp_path / "out"
    common = ("--out", str(out), "--bench-file", str(bench))
    assert run("jog", "--confirm-motion", *common)[0] == EXIT_ORDER
    assert run("probe", *common)[0] == EXIT_OK
    assert passed_steps(out) == ["probe"]
    code, err = run("jog", *common)
    assert code == EXIT_USAGE and "--confirm-motion" in err
    assert run("jog", "--confirm-motion", *common)[0] == EXIT_OK
    assert passed_steps(out) == ["probe", "jog"]
    parameters = load_parameter_file(out / "jog.yaml", "/smm/hw_bridge_node")
    assert parameters["bridge.encoder.direction"] == list(truth.direction)
    assert parameters["bridge.valve.polarity"] == list(truth.valve_polarity)
    for j in range(2):  # home: the zero offset is the raw count at q = 0, give or take the encoder's noise
        assert abs(parameters["bridge.encoder.zero_offset"][j] - truth.zero_offset[j]) < 20
        assert abs(parameters["bridge.valve.null_bias"][j] - truth.valve_null_bias[j]) < 50
        gain = CODE_MAX / truth.full_scale_torque[j] / truth.valve_gain_positive[j]
        assert abs(parameters["bridge.valve.gain"][j] / gain - 1) < 0.05
    report = (out / "REPORT.md").read_text()
    assert "## probe: passed" in report and "## jog: passed" in report
    assert (out / "probe_record.npz").is_file() and (out / "jog_record.npz").is_file()
    # probe again: the jog that ran on the old probe is forgotten
    assert run("probe", *common)[0] == EXIT_OK
    assert passed_steps(out) == ["probe"]


def test_probe_on_a_faulty_bench_exits_non_zero_and_jog_refuses(tmp_path: Path) -> None:
    bench = write_bench(tmp_path / "bench.yaml", 2, supply_pressure=3.0)
    out = tmp_path / "out"
    common = ("--out", str(out), "--bench-file", str(bench))
    code, err = run("probe", *common)
    assert code == EXIT_FAULT
    assert "FAULT: the board reports SUPPLY_LOW" in err and "supply pressure 3.00 bar" in err
    state = yaml.safe_load((out / "state.json").read_text())
    assert state["probe"]["passed"] is False and "SUPPLY_LOW" in state["probe"]["why"]
    code, err = run("jog", "--confirm-motion", *common)
    assert code == EXIT_ORDER and "it failed: the board reports SUPPLY_LOW" in err
    assert "## probe: FAILED" in (out / "REPORT.md").read_text()


class Interrupting(LockstepDevice):
    """Ctrl-C arrives after ``after`` enabled commands."""

    def __init__(self, after: int, *args: object) -> None:
        super().__init__(*args)  # type: ignore[arg-type]
        self.after = after
        self.commands: list[ValveCommand] = []

    def write(self, command: ValveCommand) -> None:
        self.commands.append(command)
        super().write(command)
        if command.enabled:
            self.after -= 1
            if self.after == 0:
                raise KeyboardInterrupt


def test_ctrl_c_during_the_jog_disables_the_valves(tmp_path: Path) -> None:
    bench = write_bench(tmp_path / "bench.yaml", 3)
    out = tmp_path / "out"
    common = ("--out", str(out), "--bench-file", str(bench))
    assert run("probe", *common)[0] == EXIT_OK
    device = Interrupting(500, draw_bench(3))
    arguments = cli.parser().parse_args(["jog", "--confirm-motion", *common])
    err = io.StringIO()
    assert (
        cli.jog_command(arguments, io.StringIO(), err, opener=lambda _: _opened(device)) == EXIT_INTERRUPTED
    )
    assert "interrupted; the valves are disabled" in err.getvalue()
    assert device.commands[-1].enabled is False and not device.board.status_enabled
    assert passed_steps(out) == ["probe"]


def _opened(device: LockstepDevice) -> LockstepDevice:
    device.open()
    return device


def test_a_jog_that_stops_leaves_the_bench_disabled_and_says_why(tmp_path: Path) -> None:
    bench = write_bench(tmp_path / "bench.yaml", 4)
    out = tmp_path / "out"
    common = ("--out", str(out), "--bench-file", str(bench))
    assert run("probe", *common)[0] == EXIT_OK
    code, err = run("jog", "--confirm-motion", "--window", "0.01", *common)
    assert code == 3 and "widen --window" in err
    assert "valves are disabled" in err
    assert "## jog: FAILED" in (out / "REPORT.md").read_text()
    assert passed_steps(out) == ["probe"]


def test_bad_arguments_are_refused(tmp_path: Path) -> None:
    out = str(tmp_path / "out")
    with pytest.raises(SystemExit):
        cli.parser().parse_args(["probe", "--out", out, "--bench-file", "x", "--pose", "1"])
    with pytest.raises(SystemExit):
        cli.parser().parse_args(["probe", "--out", out])  # no bench
    assert cli.main(["probe", "--out", out, "--bench-file", "x", "--timeout", "0"]) == EXIT_USAGE
    code, err = run("probe", "--out", out, "--bench-file", str(tmp_path / "missing.yaml"))
    assert code == EXIT_USAGE and "cannot read bench file" in err
    code, err = run("probe", "--out", out, "--board", "nowhere")
    assert code == EXIT_USAGE and "ADDRESS:PORT" in err


def test_identify_tune_and_verify_refuse_to_run_before_the_step_before_passed(tmp_path: Path) -> None:
    bench = write_bench(tmp_path / "bench.yaml", 1)
    out = tmp_path / "out"
    common = ("--out", str(out), "--bench-file", str(bench))
    code, err = run("identify", *common)
    assert code == EXIT_USAGE and "--confirm-motion" in err
    code, err = run("identify", "--confirm-motion", *common)
    assert code == EXIT_ORDER and "identify needs jog to have passed" in err
    code, err = run("tune", "--out", str(out))
    assert code == EXIT_ORDER and "tune needs identify to have passed" in err
    code, err = run("verify", "--confirm-motion", *common)
    assert code == EXIT_ORDER and "verify needs tune to have passed" in err
    assert not (out / "commissioned.yaml").exists()


@pytest.mark.parametrize(
    "argv, field",
    [
        (("tune", "--draws", "0"), "draws"),
        (("tune", "--duration", "0.1"), "duration"),
        (("verify", "--confirm-motion", "--ready-factor", "0.5", "--bench-file", "b.yaml"), "ready_factor"),
        (("identify", "--confirm-motion", "--bootstrap", "3", "--bench-file", "b.yaml"), "bootstrap"),
    ],
)
def test_invalid_step_settings_are_usage_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: tuple[str, ...], field: str
) -> None:
    assert cli.main([*argv, "--out", str(tmp_path / "out")]) == EXIT_USAGE
    assert field in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
