"""The commands of ``smm-commission``: each takes the parsed arguments and returns an exit code.

Codes are in the link's units (:data:`~smm_commissioning.host.FULL_SCALE`): the jog's and identify's steps
are the frame link's scaled to it. Every step leaves the bench disabled however it ends (done, failed,
Ctrl-C) and says why on stderr.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

import numpy as np
from smm_analysis.identify_command import MODEL_NODES, model_sections, render_identification
from smm_analysis.parameters_file import write_parameters_file
from smm_bench_emulator.bench_file import BenchFileError
from smm_hw_bridge.bridge_config import BridgeConfig
from smm_hw_bridge.canopen_configure import ConfigureError
from smm_hw_bridge.device import Device, DeviceError
from smm_schema.fields import config_from_parameters

from smm_commissioning.closed import LoopRecord
from smm_commissioning.errors import (
    BenchFaultError,
    CommissioningError,
    LinkLostError,
    MotionStopError,
    StepOrderError,
)
from smm_commissioning.host import BenchHost, in_units, valve_units
from smm_commissioning.identify import (
    Edge,
    IdentifyConfig,
    IdentifyResult,
    excite,
    find_edges,
    fit_bag,
    write_bag,
)
from smm_commissioning.jog import JogConfig, JointJog, run_jog
from smm_commissioning.link import open_bench
from smm_commissioning.probe import ProbeConfig, ProbeResult, run_probe
from smm_commissioning.report import (
    BRIDGE_NODE,
    bridge_parameters,
    identify_markdown,
    jog_markdown,
    probe_markdown,
    tune_markdown,
    verify_markdown,
)
from smm_commissioning.steps import COMMISSIONED, record_step, require, step_entry, write_report
from smm_commissioning.tune import TuneConfig, plant_values, run_tune, tune_spec
from smm_commissioning.verify import Verdict, VerifyConfig, run_verify, settings_of
from smm_dynamics import SMMParameters

__all__ = [
    "EXIT_FAULT",
    "EXIT_INTERRUPTED",
    "EXIT_LINK",
    "EXIT_MOTION",
    "EXIT_NOT_FOUND",
    "EXIT_NOT_READY",
    "EXIT_OK",
    "EXIT_ORDER",
    "EXIT_USAGE",
    "identify_command",
    "jog_command",
    "probe_command",
    "tune_command",
    "verify_command",
]

EXIT_OK = 0
EXIT_FAULT = 1
"""probe found a fault on the bench."""
EXIT_USAGE = 2
EXIT_MOTION = 3
"""jog stopped a joint (window, speed, fault, no response)."""
EXIT_ORDER = 4
"""The step before has not passed."""
EXIT_LINK = 5
"""No feedback from the board, or it restarted."""
EXIT_NOT_READY = 6
"""verify ran, the bench tracks worse than the model allows."""
EXIT_NOT_FOUND = 7
"""identify found no sound model, or tune no gain set stable on every drawn plant."""
EXIT_INTERRUPTED = 130
_RECHECK_TICKS = 200
"""Feedbacks a motion step reads disabled before it enables anything (a short probe)."""


@contextmanager
def _session(
    arguments: argparse.Namespace, err: TextIO, opener: Callable[[argparse.Namespace], Device]
) -> Iterator[BenchHost]:
    """A host on the opened bench, made safe and closed however the step ends."""
    device = opener(arguments)
    host = BenchHost(device, timeout_s=arguments.timeout)
    try:
        yield host
    except BaseException:
        if device.faults:  # a CANopen bench's: each naming the node and the code
            print(f"smm-commission: the link's faults: {'; '.join(device.faults)}", file=err)
        raise
    finally:
        untold = host.make_safe()
        device.close()
        if untold is not None:
            print(f"smm-commission: {untold}", file=err)
        if host.enabled_ever:
            print("smm-commission: the valves are disabled (the bench holds the joints)", file=err)


def _probe_config(arguments: argparse.Namespace, ticks: int | None = None) -> ProbeConfig:
    return ProbeConfig(
        ticks=arguments.ticks if ticks is None else ticks,
        supply_min=arguments.supply_min,
        pose=arguments.pose,
    )


def probe_command(
    arguments: argparse.Namespace,
    out_stream: TextIO = sys.stdout,
    err: TextIO = sys.stderr,
    opener: Callable[[argparse.Namespace], Device] = open_bench,
) -> int:
    """``smm-commission probe``: reads the bench disabled; 0 when it passed, 1 on a fault."""
    out: Path = arguments.out
    config = _probe_config(arguments)
    try:
        with _session(arguments, err, opener) as host:
            try:
                result = run_probe(host, config)
            finally:
                out.mkdir(parents=True, exist_ok=True)
                host.save(out / "probe_record.npz")
    except KeyboardInterrupt:
        print("smm-commission probe: interrupted; nothing was enabled", file=err)
        return EXIT_INTERRUPTED
    except (CommissioningError, DeviceError, BenchFileError, ValueError) as error:
        return _failed(out, "probe", error, err)
    (out / "probe.md").write_text(probe_markdown(result, config), encoding="utf-8")
    summary = {
        "counts_at_pose": list(result.counts_at_pose),
        "pose": list(result.pose),
        "counts_std": list(result.counts_std),
    }
    write_parameters_file(
        out / "probe.yaml",
        {BRIDGE_NODE: {"bridge.encoder.zero_offset": list(result.counts_at_pose)}},
        comment="smm-commission probe: raw counts at the confirmed pose (the zero once jog found the "
        "encoders' direction; at home, the zero itself)",
    )
    record_step(out, "probe", result.passed, summary, "; ".join(result.findings))
    write_report(out)
    print(probe_markdown(result, config), file=out_stream)
    if not result.passed:
        for finding in result.findings:
            print(f"smm-commission probe: FAULT: {finding}", file=err)
        return EXIT_FAULT
    return EXIT_OK


def _failed(out: Path, step: str, error: BaseException, err: TextIO) -> int:
    """Reports a failed step: why on stderr, in the state file and the report; its exit code."""
    print(f"smm-commission {step}: {error}", file=err)
    if isinstance(error, StepOrderError):
        return EXIT_ORDER
    if isinstance(error, (BenchFileError, ValueError)) and not isinstance(error, CommissioningError):
        return EXIT_USAGE
    record_step(out, step, False, {}, str(error))
    section = (
        jog_markdown((), JogConfig(), str(error))
        if step == "jog"
        else f"## {step}: FAILED\n\nStopped: {error}. The valves are disabled.\n"
    )
    (out / f"{step}.md").write_text(section, encoding="utf-8")
    write_report(out)
    if isinstance(error, (BenchFaultError, ConfigureError)):  # a CANopen node missing, of another type, ...
        return EXIT_FAULT
    if isinstance(error, MotionStopError):
        return EXIT_MOTION
    if isinstance(error, (LinkLostError, DeviceError)):
        return EXIT_LINK
    return EXIT_NOT_FOUND


def _recheck(host: BenchHost, arguments: argparse.Namespace) -> ProbeResult:
    """A short probe before any motion: a bench that changed since probe passed enables nothing."""
    result = run_probe(host, _probe_config(arguments, _RECHECK_TICKS))
    if not result.passed:
        raise BenchFaultError(list(result.findings))
    return result


def _bridge(parameters: Mapping[str, object], lockstep: bool) -> BridgeConfig:
    """The bridge's config of a step's ``bridge.*`` parameters (raises ValueError as a node would)."""
    return config_from_parameters(BridgeConfig, BridgeConfig(lockstep=lockstep), parameters, prefix="bridge")


def _motion(
    arguments: argparse.Namespace,
    step: str,
    work: Callable[[BenchHost], None],
    *,
    err: TextIO,
    opener: Callable[[argparse.Namespace], Device],
    record: str = "",
) -> int | None:
    """Runs ``work`` on the bench after a short probe, made safe however it ends; None when it passed.

    Else the exit code, the failure recorded. ``record``: the name of its record (default the step's).
    """
    out: Path = arguments.out
    if not arguments.confirm_motion:
        print(f"smm-commission {step}: moves the joints; clear the bench and pass --confirm-motion", file=err)
        return EXIT_USAGE
    try:
        require(out, step)
    except StepOrderError as error:
        return _failed(out, step, error, err)
    try:
        with _session(arguments, err, opener) as host:
            try:
                _recheck(host, arguments)
                work(host)
            finally:
                host.save(out / f"{record or step}_record.npz")
    except KeyboardInterrupt:
        print(f"smm-commission {step}: interrupted; the valves are disabled", file=err)
        record_step(out, step, False, {}, "interrupted by the operator")
        return EXIT_INTERRUPTED
    except (CommissioningError, DeviceError, BenchFileError, ValueError) as error:
        return _failed(out, step, error, err)
    return None


def jog_command(
    arguments: argparse.Namespace,
    out_stream: TextIO = sys.stdout,
    err: TextIO = sys.stderr,
    opener: Callable[[argparse.Namespace], Device] = open_bench,
) -> int:
    """``smm-commission jog --confirm-motion``: the valves' and encoders' truths; 0 when it passed."""
    out: Path = arguments.out
    config = in_units(
        JogConfig(window=arguments.window, velocity_limit=arguments.velocity_limit),
        arguments.link,
        ("search_step", "search_max", "stair_step"),
    )
    found: list[tuple[JointJog, ...]] = []
    failed = _motion(
        arguments, "jog", lambda host: found.append(run_jog(host, config)), err=err, opener=opener
    )
    if failed is not None:
        return failed
    probe = step_entry(out, "probe")
    counts = (int(probe["counts_at_pose"][0]), int(probe["counts_at_pose"][1]))
    pose = (float(probe["pose"][0]), float(probe["pose"][1]))
    results = found[0]
    parameters = {**bridge_parameters(results, counts, pose, config.encoder), **valve_units(arguments.link)}
    write_parameters_file(
        out / "jog.yaml",
        {BRIDGE_NODE: parameters},
        comment="smm-commission jog: the valves' and encoders' truths (smm-launch --params-file)",
    )
    (out / "jog.md").write_text(jog_markdown(results, config), encoding="utf-8")
    record_step(out, "jog", True, {"parameters": parameters})
    write_report(out)
    print(jog_markdown(results, config), file=out_stream)
    return EXIT_OK


def identify_command(
    arguments: argparse.Namespace,
    out_stream: TextIO = sys.stdout,
    err: TextIO = sys.stderr,
    opener: Callable[[argparse.Namespace], Device] = open_bench,
) -> int:
    """``smm-commission identify --confirm-motion``: the model, the valves' gains and null; 0 when passed.

    Two sessions on the bench: the excitation, then (after the fit, the bench idle and disabled) the
    overlap's edges.
    """
    out: Path = arguments.out
    config = in_units(
        IdentifyConfig(bootstrap=arguments.bootstrap, window=arguments.window),
        arguments.link,
        ("edge_span", "edge_step"),
    )
    jog = step_entry(out, "jog").get("parameters", {})
    lockstep = arguments.bench_file is not None
    records: list[LoopRecord] = []
    edges: list[tuple[Edge, ...]] = []
    failed = _motion(
        arguments,
        "identify",
        lambda host: records.append(excite(host, _bridge(jog, lockstep), config)),
        err=err,
        opener=opener,
    )
    if failed is not None:
        return failed
    record = records[0]
    bag = out / "identify_bag"
    shutil.rmtree(bag, ignore_errors=True)
    try:
        identification, gain, run = fit_bag(write_bag(record, bag), config.bootstrap)
    except CommissioningError as error:
        return _failed(out, "identify", error, err)
    failed = _motion(
        arguments,
        "identify",
        lambda host: edges.append(find_edges(host, _bridge(jog, lockstep), identification.params, config)),
        err=err,
        opener=opener,
        record="identify_edges",
    )
    if failed is not None:
        return failed
    jog_bridge = _bridge(jog, lockstep)
    result = IdentifyResult(identification, gain, edges[0], record, run.warnings)
    refined = result.valve()
    try:
        parameters = {**jog, **refined}
        _bridge(parameters, lockstep)
    except (CommissioningError, ValueError) as error:
        return _failed(out, "identify", error, err)
    write_parameters_file(
        out / "identify.yaml",
        {BRIDGE_NODE: parameters, **model_sections(identification.params)},
        comment="smm-commission identify: the valves refined, the identified model "
        "(smm-launch --params-file)",
    )
    (out / "identify_identification.md").write_text(
        render_identification(identification, [run], [], gain=gain), encoding="utf-8"
    )
    section = identify_markdown(result, jog_bridge, refined)
    (out / "identify.md").write_text(section, encoding="utf-8")
    model = model_sections(identification.params)[MODEL_NODES[0]]
    summary = {"parameters": parameters, "model": model, "interval": identification.interval.tolist()}
    record_step(out, "identify", True, summary)
    write_report(out)
    print(section, file=out_stream)
    return EXIT_OK


def _model(values: Mapping[str, object]) -> SMMParameters:
    """SMMParameters of ``model.*`` values (lists as tuples)."""
    return SMMParameters(
        **{name[6:]: tuple(v) if isinstance(v, list) else v for name, v in values.items()}  # type: ignore[arg-type]
    )


def tune_command(
    arguments: argparse.Namespace, out_stream: TextIO = sys.stdout, err: TextIO = sys.stderr
) -> int:
    """``smm-commission tune``: the sweep on the identified model, the chosen gains; 0 when it passed."""
    out: Path = arguments.out
    config = TuneConfig(
        duration=arguments.duration, draws=arguments.draws, seed=arguments.seed, workers=arguments.workers
    )
    try:
        require(out, "tune")
    except StepOrderError as error:
        return _failed(out, "tune", error, err)
    identify, probe = step_entry(out, "identify"), step_entry(out, "probe")
    try:
        bridge = _bridge(identify["parameters"], False)
        quantum = bridge.encoder.quantum
        noise = (float(probe["counts_std"][0] * quantum[0]), float(probe["counts_std"][1] * quantum[1]))
        plant = plant_values(_model(identify["model"]), bridge, noise)
        document = tune_spec(np.asarray(identify["interval"]), plant, config)
        folder = out / "tune"
        shutil.rmtree(folder, ignore_errors=True)
        result = run_tune(document, folder, config)
    except (CommissioningError, ValueError, KeyError) as error:
        return _failed(out, "tune", CommissioningError(str(error)), err)
    write_parameters_file(
        out / "tune.yaml",
        result.sections,
        comment="smm-commission tune: the chosen gains on the identified model (smm-launch --params-file)",
    )
    section = tune_markdown(result, config)
    (out / "tune.md").write_text(section, encoding="utf-8")
    gains = result.spec.gain_sets[result.chosen]
    record_step(out, "tune", True, {"spec": document, "gains": gains, "sections": result.sections})
    write_report(out)
    print(section, file=out_stream)
    return EXIT_OK


def verify_command(
    arguments: argparse.Namespace,
    out_stream: TextIO = sys.stdout,
    err: TextIO = sys.stderr,
    opener: Callable[[argparse.Namespace], Device] = open_bench,
) -> int:
    """``smm-commission verify --confirm-motion``: case 1 on the commissioned parameters.

    Writes ``commissioned.yaml`` and returns 0 when the bench is ready, 6 when it is not.
    """
    out: Path = arguments.out
    config = VerifyConfig(duration=arguments.duration, ready_factor=arguments.ready_factor)
    identify, tune = step_entry(out, "identify"), step_entry(out, "tune")
    lockstep = arguments.bench_file is not None
    verdicts: list[Verdict] = []

    def close(host: BenchHost) -> None:
        verdicts.append(
            run_verify(host, _bridge(identify["parameters"], lockstep), settings_of(tune, config), config)
        )

    failed = _motion(arguments, "verify", close, err=err, opener=opener)
    if failed is not None:
        return failed
    verdict = verdicts[0]
    section = verify_markdown(verdict, config)
    (out / "verify.md").write_text(section, encoding="utf-8")
    summary = {
        "ready": verdict.ready,
        "bench_rms": list(verdict.bench),
        "predicted_rms": list(verdict.predicted),
    }
    if verdict.ready:
        write_parameters_file(
            out / COMMISSIONED,
            {BRIDGE_NODE: identify["parameters"], **tune["sections"]},
            comment="smm-commission: the commissioned bench (smm-launch --plant hardware --params-file)",
        )
    why = "" if verdict.ready else f"case-1 RMS {verdict.ratio[0]:.2f}x / {verdict.ratio[1]:.2f}x the model's"
    record_step(out, "verify", verdict.ready, summary, why)
    write_report(out)
    print(section, file=out_stream)
    return EXIT_OK if verdict.ready else EXIT_NOT_READY
