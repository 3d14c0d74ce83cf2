"""``smm-bag identify BAG [BAG...] [--validate BAG] [--out DIR]``: the plant's parameters from recorded runs.

The command layer: :func:`add_identify_parser` adds the subcommand to a parser, :func:`identify_command`
takes the parsed arguments and returns an exit code; the work is :mod:`smm_analysis.identification`, each
run streamed in bounded memory (:mod:`smm_analysis.identification.streaming`). Writes ``model.yaml``
(``model.*`` of controller_node and fleso_node), ``REPORT.md`` and PNG figures.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, TextIO

import numpy as np
from smm_bag.errors import BagError
from smm_bag.exit_codes import EXIT_MISSING_TOPICS, EXIT_OK, EXIT_USAGE, fail
from smm_bag.progress import Progress
from smm_controller.excitation import ExcitationReference

from smm_analysis.errors import IdentificationError, MissingSignalsError, NotExcitingError
from smm_analysis.identification import (
    PARAMETER_NAMES,
    PARAMETER_UNITS,
    EstimationSettings,
    FilterSettings,
    Identification,
    RunFit,
    parameter_vector,
)
from smm_analysis.identification.estimate import estimate
from smm_analysis.identification.excitation import excitation_quality
from smm_analysis.identification.plots import RunFigures, write_identification_plots
from smm_analysis.identification.streaming import StreamedRun, draw_fit, read_run
from smm_analysis.identification.valve_gain import DIRECTIONS, ValveGain, estimate_gain
from smm_analysis.parameters_file import write_parameters_file
from smm_analysis.runs.commands import streams_of
from smm_analysis.runs.window import TimeWindow, add_reading_options, window_from_options
from smm_dynamics import SMMParameters

__all__ = [
    "MODEL_NODES",
    "add_identify",
    "add_identify_parser",
    "identify_command",
    "model_sections",
    "render_identification",
]

#: Nodes that read ``model.*`` (the controller's nominal model), as parameters-file keys.
MODEL_NODES = ("/**/controller_node", "/**/fleso_node")
_STREAMING_NOTE = (
    "each run filtered in pieces with an overlap that leaves the low-pass's transient below one rounding, "
    "its rows reduced to normal equations per bootstrap block as they come (docs/IDENTIFICATION.md, "
    '"Streaming").'
)
_VALVE_NOTE = (
    "Applied torque: `joint_states` effort, the mean torque over the control interval before each stamp. "
    "On the simulator it is the torque that acted; through the bridge it is the bridge's valve model's "
    "torque (the emulator's valve matches it when both use the same `valve.*` parameters), so the "
    "identified friction and offset include whatever the valve model does not describe."
)
_MEASURED_NOTE = (
    "Torque: the bridge's measured torque (`hw_bridge_internals` `measured_torque`, from the load "
    "pressure), the torque that acted; the valve's gain is measured over modelled torque (`joint_states` "
    "effort, the bridge's valve model's) per direction, so the inertias are not scaled by a wrong valve gain."
)


def _gain_lines(gain: ValveGain) -> list[str]:
    """The valve's gain table (Markdown)."""
    lines = [
        "| joint | direction | gain (measured / modelled) | 95 % interval | rows |",
        "|---|---|---|---|---|",
    ]
    for j, joint in enumerate(("alpha", "beta")):
        for d, direction in enumerate(DIRECTIONS):
            low, high = gain.interval[j, d]
            lines.append(
                f"| {joint} | {direction} | {gain.ratio[j, d]:.5g} | [{low:.5g}, {high:.5g}] | "
                f"{int(gain.rows[j, d])} |"
            )
    return lines


def add_identify_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Adds ``identify`` to ``smm-bag``'s subparsers; returns its parser."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "identify", help="estimate the plant's inertias, gravity lever and friction from excitation runs"
    )
    parser.add_argument("bags", type=Path, nargs="+", metavar="BAG", help="identification runs")
    parser.add_argument(
        "--validate", type=Path, action="append", default=[], metavar="BAG", help="validation run"
    )
    parser.add_argument("--out", type=Path, help="write model.yaml, REPORT.md and figures here")
    parser.add_argument("--cutoff", type=float, default=FilterSettings.cutoff, help="low-pass corner (Hz)")
    parser.add_argument("--bootstrap", type=int, default=EstimationSettings.bootstrap, help="replicates")
    parser.add_argument("--no-plots", action="store_true", help="with --out: no figures")
    add_reading_options(
        parser,
        segments_help="each experiment found in a bag (armed stretches, parameter changes) is a run of "
        "its own",
    )
    return parser


def _base_model(parameters: Mapping[str, Mapping[str, Any]]) -> SMMParameters:
    """Gravity, its sign and L of the recorded controller's model (defaults if the bag has none)."""
    for node, values in parameters.items():
        if node.rstrip("/").endswith("controller_node"):
            known = {
                key: values[f"model.{key}"]
                for key in ("gravity", "gravity_sign", "link_length")
                if isinstance(values.get(f"model.{key}"), float)
            }
            try:
                return SMMParameters(**known)
            except ValueError:
                break
    return SMMParameters()


def recorded_excitation(parameters: Mapping[str, Mapping[str, Any]]) -> ExcitationReference | None:
    """The ``excite`` reference a run followed, from the recorded node parameters, or None."""
    for node, values in parameters.items():
        for prefix, kind_key in (("reference.", "reference.kind"), ("", "kind")):
            if not node.rstrip("/").endswith(("controller_node", "reference_node")):
                continue
            if values.get(kind_key) != "excite":
                continue
            start = f"{prefix}excite."
            fields: dict[str, Any] = {
                key[len(start) :]: tuple(value) if isinstance(value, list) else value
                for key, value in values.items()
                if key.startswith(start)
            }
            try:
                return ExcitationReference(**fields)
            except (TypeError, ValueError):
                return None
    return None


def _excitation_lines(reference: ExcitationReference | None) -> list[str]:
    if reference is None:
        return []
    quality = excitation_quality(reference)
    return [
        "",
        f"Excitation (the recorded `excite` reference): crest factor of q_d' {quality.crest_factor[0]:.3g} "
        f"(alpha), {quality.crest_factor[1]:.3g} (beta); condition number of the column-scaled regressor "
        f"over q_d {quality.condition_number:.3g}.",
    ]


def model_sections(params: SMMParameters) -> dict[str, dict[str, object]]:
    """``model.*`` of every node reading the model, for :func:`write_parameters_file`."""
    values: dict[str, object] = {
        "model.I11": params.I11,
        "model.I22": params.I22,
        "model.I44": params.I44,
        "model.I55": params.I55,
        "model.mass_lever": params.mass_lever,
        "model.gravity": params.gravity,
        "model.gravity_sign": params.gravity_sign,
        "model.viscous_friction": list(params.viscous_friction),
        "model.coulomb_friction": list(params.coulomb_friction),
        "model.torque_offset": list(params.torque_offset),
        "model.link_length": params.link_length,
    }
    return {node: dict(values) for node in MODEL_NODES}


def _estimate_lines(result: Identification) -> list[str]:
    nominal = parameter_vector(SMMParameters())
    lines = [
        "| parameter | estimate | standard error | 95 % interval | nominal (paper) | unit |",
        "|---|---|---|---|---|---|",
    ]
    for index, (name, unit) in enumerate(zip(PARAMETER_NAMES, PARAMETER_UNITS, strict=True)):
        bound = " (at its bound)" if name in result.at_bound else ""
        low, high = result.interval[index]
        lines.append(
            f"| {name} | {result.theta[index]:.6g}{bound} | {result.standard_error[index]:.3g} | "
            f"[{low:.6g}, {high:.6g}] | {nominal[index]:.6g} | {unit} |"
        )
    return lines


def _fit_rows(label: str, fits: Sequence[RunFit]) -> list[str]:
    return [f"| {label} | {fit.name} | {fit.nrmse[0]:.4f} | {fit.nrmse[1]:.4f} |" for fit in fits]


def render_identification(
    result: Identification,
    runs: Sequence[StreamedRun],
    validation: Sequence[RunFit],
    figures: Sequence[Path] = (),
    excitation: ExcitationReference | None = None,
    *,
    gain: ValveGain | None = None,
) -> str:
    """The Markdown report of an identification (``excitation``: the recorded reference, if known)."""
    lines = [
        "# Identification report",
        "",
        f"Runs: {', '.join(run.name for run in runs)}. {result.rows} joint rows used.",
        "",
        f"Read in bounded memory: {_STREAMING_NOTE}",
        "",
        f"Filtering: {runs[0].settings.describe()}.",
        "",
        f"Estimator: bounded least squares (scipy.optimize.lsq_linear, BVLS) on the column-scaled regressor, "
        f"each joint's rows weighted by 1/RMS of its residual; bounds: inertias > 0, gravity lever and "
        f"friction >= 0, offsets free. Intervals: block bootstrap over {result.settings.block:g} s segments, "
        f"{result.settings.bootstrap} replicates, 95 % percentile intervals; standard error = bootstrap "
        "standard deviation.",
        "",
        _VALVE_NOTE if gain is None else _MEASURED_NOTE,
        "",
        *_estimate_lines(result),
        "",
        f"Identifiability: rank {result.rank} of {len(PARAMETER_NAMES)}, condition number of the "
        f"column-scaled regressor {result.condition_number:.3g}; every parameter is separated by these data.",
        *_excitation_lines(excitation),
        "",
        f"Physical: smallest eigenvalue of M(q) on |alpha|, |beta| <= {result.settings.workspace} rad: "
        f"{result.min_mass_eigenvalue:.4g} kg m^2 (positive definite).",
        "",
        *(
            []
            if gain is None
            else [
                "## Valve gain per direction of the modelled torque",
                "",
                "Divide `bridge.valve.gain` (codes per N m, positive torque) and "
                "`bridge.valve.gain_negative` by these to match the valve (a negative ratio: the valve's "
                "polarity is reversed).",
                "",
                *_gain_lines(gain),
                "",
            ]
        ),
        "## Fit (torque NRMSE = RMS(measured - model) / RMS(measured), used rows)",
        "",
        "| role | run | alpha | beta |",
        "|---|---|---|---|",
        *_fit_rows("identification", result.fits),
        *_fit_rows("validation", validation),
    ]
    warnings = [warning for run in runs for warning in run.warnings]
    if warnings:
        lines += ["", "## Left out", "", *(f"- {warning}" for warning in warnings)]
    if figures:
        lines += ["", "## Figures", "", *(f"![{path.stem}]({path.name})" for path in figures)]
    lines += [
        "",
        "Use: `controller_node --ros-args --params-file model.yaml` (and `fleso_node` in the split",
        "chain), or `smm-launch --params-file model.yaml`; see docs/IDENTIFICATION.md.",
    ]
    return "\n".join(lines) + "\n"


def add_identify(subparsers: Any) -> None:
    """Add ``smm-bag identify`` (an entry point of group ``smm_bag.commands``)."""
    add_identify_parser(subparsers).set_defaults(handler=identify_command)


def _read_runs(
    args: argparse.Namespace,
    *,
    window: TimeWindow,
    settings: FilterSettings,
    block: float,
    directory: Path,
    err: TextIO,
) -> tuple[list[StreamedRun], list[StreamedRun], SMMParameters, ExcitationReference | None]:
    """The identification and validation runs of the bags (their windows or segments), streamed."""
    runs: dict[str, list[StreamedRun]] = {"identification": [], "validation": []}
    base: SMMParameters | None = None
    excitation: ExcitationReference | None = None
    bags = [*((bag, "identification") for bag in args.bags), *((bag, "validation") for bag in args.validate)]
    for bag, role in bags:
        streams = streams_of(bag, window=window, segments=args.segments, quiet=args.quiet, err=err)
        for stream, label in streams:
            if base is None:
                base = _base_model(stream.manifest.parameters)
                excitation = recorded_excitation(stream.manifest.parameters)
            name = str(bag) if label is None else f"{bag} {label}"
            if not window.whole:
                name += f" [{window.describe()}]"
            runs[role].append(
                read_run(
                    name,
                    stream,
                    directory / f"{len(runs['identification']) + len(runs['validation'])}.spool",
                    settings,
                    gravity=base.gravity,
                    gravity_sign=base.gravity_sign,
                    block=block,
                    progress=Progress(f"preparing {name}", 1, err, enabled=not args.quiet),
                )
            )
    assert base is not None
    return runs["identification"], runs["validation"], base, excitation


def _valve_gain(runs: Sequence[StreamedRun], estimation: EstimationSettings, err: TextIO) -> ValveGain | None:
    """The valve's gain when every run has the measured torque; None (and why, on ``err``) otherwise."""
    measured = [run.gain for run in runs if run.gain is not None]
    if not measured or len(measured) < len(runs):
        return None
    try:
        return estimate_gain(measured, estimation.bootstrap, estimation.seed)
    except NotExcitingError as error:
        err.write(f"warning: no valve gain: {error}\n")
        return None


def identify_command(
    args: argparse.Namespace, stdout: TextIO | None = None, stderr: TextIO | None = None
) -> int:
    """``smm-bag identify``: prints the estimates; with ``--out`` writes model.yaml, REPORT.md, figures."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        settings = FilterSettings(cutoff=args.cutoff)
        estimation = EstimationSettings(bootstrap=args.bootstrap)
        window = window_from_options(args)
    except ValueError as error:
        err.write(f"smm-bag: error: {error}\n")
        return EXIT_USAGE
    if args.segments and not window.whole:
        err.write("smm-bag: error: --segments finds its own windows: give it without --start / --end\n")
        return EXIT_USAGE
    with tempfile.TemporaryDirectory(prefix="smm-identify-") as directory:
        try:
            runs, validation_runs, base, excitation = _read_runs(
                args,
                window=window,
                settings=settings,
                block=estimation.block,
                directory=Path(directory),
                err=err,
            )
            if not args.quiet:
                err.write(f"estimating ({estimation.bootstrap} bootstrap replicates)\n")
            result = estimate([run.sums for run in runs], base, estimation)
            gain = _valve_gain(runs, estimation, err)
        except BagError as error:
            return fail(error, err)
        except MissingSignalsError as error:
            err.write(f"smm-bag: error: {error}\n")
            return EXIT_MISSING_TOPICS
        except IdentificationError as error:
            err.write(f"smm-bag: error: {error}\n")
            return EXIT_USAGE
        validation = [RunFit(run.name, run.sums.nrmse(result.theta)) for run in validation_runs]
        for run in [*runs, *validation_runs]:
            for warning in run.warnings:
                err.write(f"warning: {warning}\n")
        figures: list[Path] = []
        if args.out is not None:
            args.out.mkdir(parents=True, exist_ok=True)
            if not args.no_plots:
                figures = write_identification_plots(
                    [
                        RunFigures(
                            role,
                            run.name,
                            fit.nrmse,
                            draw_fit(
                                run,
                                result.theta,
                                Progress(f"drawing {run.name}", 1, err, enabled=not args.quiet),
                            ),
                            run.excitation,
                        )
                        for role, group, fits in (
                            ("identification", runs, result.fits),
                            ("validation", validation_runs, validation),
                        )
                        for run, fit in zip(group, fits, strict=True)
                    ],
                    args.out,
                )
            model = write_parameters_file(
                args.out / "model.yaml",
                model_sections(result.params),
                comment=f"Identified by smm-bag identify from {', '.join(run.name for run in runs)}.\n"
                "Use with --params-file (controller_node, fleso_node); see REPORT.md.",
            )
            report = args.out / "REPORT.md"
            report.write_text(
                render_identification(result, runs, validation, figures, excitation, gain=gain),
                encoding="utf-8",
            )
            err.write(f"wrote {model}, {report} and {len(figures)} figures\n")
    out.write("\n".join(_estimate_lines(result)) + "\n")
    out.write(
        f"rank {result.rank} of {len(PARAMETER_NAMES)}, condition number {result.condition_number:.3g}\n"
    )
    if gain is not None:
        out.write("valve gain (measured / modelled torque):\n" + "\n".join(_gain_lines(gain)) + "\n")
    for fit in [*result.fits, *validation]:
        out.write(f"NRMSE {fit.name}: alpha {fit.nrmse[0]:.4f}, beta {fit.nrmse[1]:.4f}\n")
    return EXIT_OK if np.all(np.isfinite(result.theta)) else EXIT_USAGE
