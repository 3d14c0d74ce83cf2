"""The commands of ``smm-commission``: each takes the parsed arguments and returns an exit code.

Every step leaves the bench disabled however it ends (done, failed, Ctrl-C) and says why on stderr.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

from smm_analysis.parameters_file import write_parameters_file
from smm_bench_emulator.bench_file import BenchFileError, load_bench_file
from smm_hw_bridge.bridge_config import BridgeConfig
from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.device import Device, DeviceError
from smm_hw_bridge.frame_device import udp_device
from smm_hw_bridge.transport import LinkConfig

from smm_commissioning.emulated import LockstepDevice
from smm_commissioning.errors import (
    BenchFaultError,
    CommissioningError,
    MotionStopError,
    StepOrderError,
)
from smm_commissioning.host import BenchHost
from smm_commissioning.jog import JogConfig, run_jog
from smm_commissioning.probe import ProbeConfig, ProbeResult, run_probe
from smm_commissioning.report import BRIDGE_NODE, bridge_parameters, jog_markdown, probe_markdown
from smm_commissioning.steps import record_step, require, step_entry, write_report

__all__ = [
    "EXIT_FAULT",
    "EXIT_INTERRUPTED",
    "EXIT_LINK",
    "EXIT_MOTION",
    "EXIT_OK",
    "EXIT_ORDER",
    "EXIT_USAGE",
    "jog_command",
    "probe_command",
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
EXIT_INTERRUPTED = 130
_RECHECK_TICKS = 200
"""Feedbacks a motion step reads disabled before it enables anything (a short probe)."""


def parse_address(text: str) -> tuple[str, int]:
    """``ADDRESS:PORT`` -> (address, port).

    Raises:
        ValueError: Not ADDRESS:PORT with a port in [0, 65535].
    """
    address, _, port = text.rpartition(":")
    if not address or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"expected ADDRESS:PORT, got {text!r}")
    return address, int(port)


def open_bench(arguments: argparse.Namespace) -> Device:
    """The bench the arguments name: the emulator in this process (``--bench-file``) or a board over UDP.

    Raises:
        BenchFileError: The bench file is invalid.
        DeviceError: The link cannot be opened.
        ValueError: A malformed address.
    """
    if arguments.bench_file is not None:
        device: Device = LockstepDevice(load_bench_file(arguments.bench_file))
    else:
        board = parse_address(arguments.board)
        bind = parse_address(arguments.bind)
        link = LinkConfig(
            bind_address=bind[0], bind_port=bind[1], board_address=board[0], board_port=board[1]
        )
        device = udp_device(link, CanopenConfig(), BridgeConfig())
    device.open()
    return device


@contextmanager
def _session(
    arguments: argparse.Namespace, err: TextIO, opener: Callable[[argparse.Namespace], Device]
) -> Iterator[BenchHost]:
    """A host on the opened bench, made safe and closed however the step ends."""
    device = opener(arguments)
    host = BenchHost(device, timeout_s=arguments.timeout)
    try:
        yield host
    finally:
        host.make_safe()
        device.close()
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
    summary = {"counts_at_pose": list(result.counts_at_pose), "pose": list(result.pose)}
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
    if step == "jog":
        (out / "jog.md").write_text(jog_markdown((), JogConfig(), str(error)), encoding="utf-8")
    write_report(out)
    if isinstance(error, BenchFaultError):
        return EXIT_FAULT
    if isinstance(error, MotionStopError):
        return EXIT_MOTION
    return EXIT_LINK


def _recheck(host: BenchHost, arguments: argparse.Namespace) -> ProbeResult:
    """A short probe before any motion: a bench that changed since probe passed enables nothing."""
    result = run_probe(host, _probe_config(arguments, _RECHECK_TICKS))
    if not result.passed:
        raise BenchFaultError(list(result.findings))
    return result


def jog_command(
    arguments: argparse.Namespace,
    out_stream: TextIO = sys.stdout,
    err: TextIO = sys.stderr,
    opener: Callable[[argparse.Namespace], Device] = open_bench,
) -> int:
    """``smm-commission jog --confirm-motion``: the valves' and encoders' truths; 0 when it passed."""
    out: Path = arguments.out
    if not arguments.confirm_motion:
        print(
            "smm-commission jog: moves the joints open loop; clear the bench and pass --confirm-motion",
            file=err,
        )
        return EXIT_USAGE
    try:
        require(out, "jog")
    except StepOrderError as error:
        return _failed(out, "jog", error, err)
    probe = step_entry(out, "probe")
    config = JogConfig(window=arguments.window, velocity_limit=arguments.velocity_limit)
    try:
        with _session(arguments, err, opener) as host:
            try:
                _recheck(host, arguments)
                results = run_jog(host, config)
            finally:
                host.save(out / "jog_record.npz")
    except KeyboardInterrupt:
        print("smm-commission jog: interrupted; the valves are disabled", file=err)
        record_step(out, "jog", False, {}, "interrupted by the operator")
        return EXIT_INTERRUPTED
    except (CommissioningError, DeviceError, BenchFileError, ValueError) as error:
        return _failed(out, "jog", error, err)
    counts = (int(probe["counts_at_pose"][0]), int(probe["counts_at_pose"][1]))
    pose = (float(probe["pose"][0]), float(probe["pose"][1]))
    parameters = bridge_parameters(results, counts, pose, config.encoder)
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
