"""``smm-reproduce``: the paper's scenarios with every controller, their metrics and report.

:func:`main` parses, :func:`reproduce` runs the command and returns the exit code (0 success; 1 ``--check``
and a claim not met; 2 bad arguments or an analysis error). Options and the command that makes the
committed docs: docs/REPRODUCTION.md and README.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from smm_analysis.closed_loop import DEFAULT_CONTROL_PERIOD
from smm_analysis.errors import AnalysisError
from smm_analysis.metrics import Group, metrics_of
from smm_analysis.reproduction.acceptance import acceptance_verdict
from smm_analysis.reproduction.energy_report import write_energy_plot
from smm_analysis.reproduction.energy_study import EnergyStudy, run_energy_study
from smm_analysis.reproduction.metrics_json import metrics_document
from smm_analysis.reproduction.plots import write_plots
from smm_analysis.reproduction.report import render_report
from smm_analysis.reproduction.reproduce import (
    REPRODUCTION_CONTROLLERS,
    resolve_controllers,
    resolve_scenarios,
    run_reproduction,
)
from smm_analysis.reproduction.results import JOINTS, ReproductionResult, RunResult
from smm_analysis.reproduction.retuned import RETUNED_SETS, controller_label
from smm_analysis.reproduction.tune_td import TDSweepPoint, sweep_td
from smm_analysis.scenarios import SCENARIOS
from smm_controller import TrackingDifferentiatorConfig

__all__ = ["ReproduceOptions", "build_parser", "main", "reproduce"]

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_ERROR = 2


@dataclass(frozen=True)
class ReproduceOptions:
    """Parsed options of ``smm-reproduce``.

    Attributes:
        out: Output folder, or None to only print.
        scenarios: Scenario names.
        controllers: Controller names.
        seed: Noise seed.
        duration: Length override for every scenario (s), or None for the paper's.
        td_speed: TD sigma for both joints (rad/s^2), or None for the default.
        td_filter_factor: TD h for both joints (s), or None for the default.
        plots: Write PNG figures (with ``out``).
        plots_dir: Folder for the figures (default: ``out``).
        report: Path of the Markdown report (default: ``out/REPORT.md``).
        td_sweep: Also run the TD sweep and put its table in the report.
        step_study: Also run the FPDESO step discretisation study.
        energy_study: Also run the torque-noise study of issue #15 (terms and settings sweep).
        check: Exit with 1 if an acceptance check fails.
        quiet: Print nothing but errors.
        command: The command line, quoted in the report.
    """

    out: Path | None
    scenarios: tuple[str, ...]
    controllers: tuple[str, ...]
    seed: int
    duration: float | None
    td_speed: float | None
    td_filter_factor: float | None
    plots: bool
    plots_dir: Path | None
    report: Path | None
    td_sweep: bool
    step_study: bool
    energy_study: bool
    check: bool
    quiet: bool
    command: str


def _names(values: Sequence[str]) -> tuple[str, ...]:
    """Accepts both ``--x a b`` and ``--x a,b``."""
    return tuple(name for value in values for name in value.split(",") if name)


def _seed(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"seed must be >= 0, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``smm-reproduce``."""
    parser = argparse.ArgumentParser(
        prog="smm-reproduce",
        description=(
            "Reproduce the FPDESO paper's simulations: every scenario x controller, metrics, report, plots."
        ),
    )
    parser.add_argument(
        "--out", type=Path, help="write metrics.json, REPORT.md and the PNG plots into this folder"
    )
    parser.add_argument(
        "--scenarios",
        nargs="+",
        default=list(SCENARIOS),
        metavar="NAME",
        help=f"scenarios to run (default: {' '.join(SCENARIOS)})",
    )
    parser.add_argument(
        "--controllers",
        nargs="+",
        default=list(REPRODUCTION_CONTROLLERS),
        metavar="NAME",
        help=(
            f"controllers to run (default: {' '.join(REPRODUCTION_CONTROLLERS)}; fpdeso_retuned is the "
            "clearly labelled retuned FPDESO set run beside the paper's gains)"
        ),
    )
    parser.add_argument("--seed", type=_seed, default=0, help="noise seed, an integer >= 0 (default 0)")
    parser.add_argument(
        "--td-speed",
        type=float,
        help="TD speed factor sigma for both joints (rad/s^2; default: smm_controller's)",
    )
    parser.add_argument(
        "--td-filter-factor",
        type=float,
        help="TD filter factor h for both joints (s; default: smm_controller's)",
    )
    parser.add_argument(
        "--duration", type=float, help="override every scenario's length (s), e.g. for a quick run"
    )
    parser.add_argument("--no-plots", dest="plots", action="store_false", help="do not write PNG figures")
    parser.add_argument("--plots-dir", type=Path, help="folder for the PNG figures (default: --out)")
    parser.add_argument("--report", type=Path, help="path of the Markdown report (default: OUT/REPORT.md)")
    parser.add_argument(
        "--td-sweep", action="store_true", help="also sweep the TD (sigma, h) on case2 (~1 min)"
    )
    parser.add_argument(
        "--step-study", action="store_true", help="also run the FPDESO step discretisation study"
    )
    parser.add_argument(
        "--energy-study",
        action="store_true",
        help="also run the case2 torque-noise study: torque terms and a sweep of the settings (~30 s)",
    )
    parser.add_argument(
        "--check",
        action="store_true",
        help=(
            "exit with 1 if an acceptance claim is not met (a step claim the paper's FPDESO gains miss "
            "counts as met only if the labelled retuned set meets it, and the output says so)"
        ),
    )
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    return parser


def _progress_line(result: RunResult, index: int, total: int) -> str:
    rms = " / ".join(f"{1e3 * result.joints[joint].RMS:.3f}" for joint in JOINTS)
    return (
        f"[{index}/{total}] {result.scenario} {result.controller}: RMS {rms} mrad ({result.wall_time:.1f} s)"
    )


def format_tables(result: ReproductionResult) -> str:
    """Plain-text tables of every run and the acceptance checks."""
    lines = []
    for scenario in result.scenarios:
        lines.append(f"{scenario.name}: {scenario.description}")
        header = f"  {'controller':<15} {'Ma (rad)':>19} {'Ave (rad)':>19} {'RMS (rad)':>19} {'eps_u':>19}"
        header += f" {'du_rms (N m)':>19}"
        if scenario.is_step:
            header += f" {'rise (s)':>15} {'overshoot (%)':>15} {'settling (s)':>15}"
        lines.append(header)
        for controller in result.controllers:
            run = result.run(scenario.name, controller)
            if run is None:
                continue
            joints = run.joints
            row = f"  {controller:<15}"
            for metric in metrics_of(Group.JOINT):
                alpha, beta = getattr(joints["alpha"], metric.name), getattr(joints["beta"], metric.name)
                pair = f"{alpha:.4g} / {beta:.4g}"
                row += f" {pair:>19}"
            if run.step is not None:
                step = run.step
                row += f" {step['alpha'].rise_time:>6.3f} / {step['beta'].rise_time:<6.3f}"
                overshoot = (100 * step["alpha"].overshoot_fraction, 100 * step["beta"].overshoot_fraction)
                row += f" {overshoot[0]:>6.2f} / {overshoot[1]:<6.2f}"
                row += f" {step['alpha'].settling_time:>6.3f} / {step['beta'].settling_time:<6.3f}"
            lines.append(row)
        lines.append("")
    retuned = [name for name in result.controllers if name in RETUNED_SETS]
    for name in retuned:
        lines.append(f"{name} = {controller_label(name)}")
    if retuned:
        lines.append("")
    if result.checks:
        lines.append("acceptance:")
        for check in result.checks:
            outcome = "pass" if check.passed else "FAIL"
            lines.append(
                f"  [{outcome}] {check.claim}, {check.joint}: {check.value:.4g} ({check.requirement})"
            )
        verdict = acceptance_verdict(result.checks)
        lines.append(f"verdict: {'claims met' if verdict.met else 'claims NOT met'}")
        lines += [f"  {line}" for line in verdict.message.splitlines()]
    return "\n".join(lines)


def _td_config(options: ReproduceOptions) -> TrackingDifferentiatorConfig:
    default = TrackingDifferentiatorConfig()
    speed = default.speed if options.td_speed is None else (options.td_speed, options.td_speed)
    factor = (
        default.filter_factor
        if options.td_filter_factor is None
        else (options.td_filter_factor, options.td_filter_factor)
    )
    if min(factor) < DEFAULT_CONTROL_PERIOD:
        raise AnalysisError(
            f"TD filter factor {factor!r} s must be >= the control period {DEFAULT_CONTROL_PERIOD} s"
        )
    try:
        return TrackingDifferentiatorConfig(speed=speed, filter_factor=factor)
    except ValueError as error:
        raise AnalysisError(f"invalid TD setting: {error}") from error


def reproduce(options: ReproduceOptions, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """Runs the reproduction and writes its outputs.

    Args:
        options: Parsed options.
        stdout: Stream for progress and tables (default: sys.stdout at call time).
        stderr: Stream for errors (default: sys.stderr at call time).

    Returns:
        The exit code (0, 1 or 2; see the module docstring).
    """
    out_stream = sys.stdout if stdout is None else stdout
    err_stream = sys.stderr if stderr is None else stderr

    def say(text: str) -> None:
        if not options.quiet:
            print(text, file=out_stream, flush=True)

    try:
        scenarios = resolve_scenarios(options.scenarios, options.duration)
        controllers = resolve_controllers(options.controllers)
        td_config = _td_config(options)
        result = run_reproduction(
            scenarios,
            controllers,
            seed=options.seed,
            td_config=td_config,
            step_study=options.step_study,
            progress=lambda run, index, total: say(_progress_line(run, index, total)),
        )
        sweep: list[TDSweepPoint] | None = None
        if options.td_sweep:
            say("TD sweep on case2 with FPDESO:")
            sweep = sweep_td(
                seed=options.seed,
                progress=lambda point: say(
                    f"  sigma {point.speed:g} h {1e3 * point.filter_factor:g} ms: RMS "
                    f"{1e3 * point.rms_alpha:.3f} / {1e3 * point.rms_beta:.3f} mrad"
                ),
            )
        study: EnergyStudy | None = None
        if options.energy_study:
            say("torque-noise study on case2:")
            study = run_energy_study(
                seed=options.seed,
                progress=lambda index, total, setting: say(f"  [{index + 1}/{total}] {setting.label}"),
            )
        say("")
        say(format_tables(result))
        if options.out is not None:
            _write_outputs(options, result, sweep, study)
            say(f"\nwrote {options.out / 'metrics.json'} and the report")
    except AnalysisError as error:
        print(f"smm-reproduce: error: {error}", file=err_stream)
        return EXIT_ERROR
    if options.check and not acceptance_verdict(result.checks).met:
        return EXIT_CHECK_FAILED
    return EXIT_OK


def _write_outputs(
    options: ReproduceOptions,
    result: ReproductionResult,
    sweep: Sequence[TDSweepPoint] | None,
    study: EnergyStudy | None = None,
) -> None:
    assert options.out is not None
    out = options.out
    report_path = options.report if options.report is not None else out / "REPORT.md"
    try:
        out.mkdir(parents=True, exist_ok=True)
        (out / "metrics.json").write_text(
            json.dumps(metrics_document(result), indent=2, allow_nan=False) + "\n", encoding="utf-8"
        )
    except OSError as error:
        raise AnalysisError(f"cannot write into {out}: {error}") from error
    plots: dict[str, str] = {}
    if options.plots:
        folder = options.plots_dir if options.plots_dir is not None else out
        paths = write_plots(result, folder)
        if study is not None:
            paths.append(write_energy_plot(study, folder / "case2_rms_vs_energy.png"))
        for path in paths:
            plots[path.stem] = Path(os.path.relpath(path.resolve(), report_path.resolve().parent)).as_posix()
    report = render_report(result, plots=plots, td_sweep=sweep, energy_study=study, command=options.command)
    try:
        report_path.parent.mkdir(parents=True, exist_ok=True)
        report_path.write_text(report, encoding="utf-8")
    except OSError as error:
        raise AnalysisError(f"cannot write {report_path}: {error}") from error


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``smm-reproduce``; returns the exit code."""
    arguments = list(sys.argv[1:] if argv is None else argv)
    parsed = build_parser().parse_args(arguments)
    options = ReproduceOptions(
        out=parsed.out,
        scenarios=_names(parsed.scenarios),
        controllers=_names(parsed.controllers),
        seed=parsed.seed,
        duration=parsed.duration,
        td_speed=parsed.td_speed,
        td_filter_factor=parsed.td_filter_factor,
        plots=parsed.plots,
        plots_dir=parsed.plots_dir,
        report=parsed.report,
        td_sweep=parsed.td_sweep,
        step_study=parsed.step_study,
        energy_study=parsed.energy_study,
        check=parsed.check,
        quiet=parsed.quiet,
        command=shlex.join(["smm-reproduce", *arguments]),
    )
    return reproduce(options)


if __name__ == "__main__":
    raise SystemExit(main())
