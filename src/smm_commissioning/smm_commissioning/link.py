"""The bench a step runs on, opened as the bridge's Device: on the frame link or the CANopen link.

The frame link: a board over UDP, or its emulator in this process; the CANopen link: a real bus, or the
emulated CANopen bench in this process. docs/COMMISSIONING.md, "On the CANopen link".
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

from smm_bench_emulator.bench_file import load_bench_file
from smm_bench_emulator.board import BoardConfig
from smm_bench_emulator.canopen_bench import eds_path
from smm_hw_bridge.bridge_config import BridgeConfig
from smm_hw_bridge.canopen_config import PARAMETERS, CanopenConfig, parameter
from smm_hw_bridge.device import Device, open_device
from smm_hw_bridge.frame_device import udp_device
from smm_hw_bridge.transport import LinkConfig
from smm_node_runtime.parameter_files import ParameterFileError, load_parameter_file
from smm_schema.fields import config_fields, config_from_parameters, parameter_name

from smm_commissioning.emulated import EMULATED_INTERFACES, CanopenLockstepDevice, LockstepDevice
from smm_commissioning.host import link_bridge

__all__ = [
    "EXTERNAL",
    "LINKS",
    "canopen_settings",
    "emulated_canopen",
    "external_canopen",
    "open_bench",
    "parse_address",
]

LINKS: Final[tuple[str, ...]] = ("frame", "canopen")
EXTERNAL: Final[str] = "external"
"""``--board`` on the CANopen link: a real bus, the devices its ``canopen.*`` name (no emulator)."""
BRIDGE_NAME: Final[str] = "/smm/hw_bridge_node"
"""The bridge's fully qualified name in smm-launch's graph: whose ``canopen.*`` a parameter file gives."""
_LOCKSTEP_HEARTBEAT_MS: Final[int] = 1000
_LOCKSTEP_PDO_VALIDITY_MS: Final[int] = 60_000
"""The emulated bench's pace is the host's (a loaded machine's): generous consumer and validity times."""


def parse_address(text: str) -> tuple[str, int]:
    """``ADDRESS:PORT`` -> (address, port).

    Raises:
        ValueError: Not ADDRESS:PORT with a port in [0, 65535].
    """
    address, _, port = text.rpartition(":")
    if not address or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"expected ADDRESS:PORT, got {text!r}")
    return address, int(port)


def canopen_settings(files: Sequence[Path]) -> CanopenConfig:
    """The CANopen link's settings: the ``canopen.*`` the bridge's parameter ``files`` set (later win).

    Commissioning answers every 1 kHz tick: ``period_us`` is 1000 whatever the files say.

    Raises:
        ValueError: A file unreadable, a ``canopen.*`` name the bridge does not know, or a bad value.
    """
    known = {parameter_name(PARAMETERS, field.name) for field in config_fields(CanopenConfig)}
    given: dict[str, Any] = {}
    for path in files:
        try:
            given.update(load_parameter_file(path, BRIDGE_NAME))
        except ParameterFileError as error:
            raise ValueError(str(error)) from error
    unknown = sorted(name for name in given if name.startswith(f"{PARAMETERS}.") and name not in known)
    if unknown:
        raise ValueError(f"unknown parameter(s) {unknown} in --params-file (known: {sorted(known)})")
    config = config_from_parameters(CanopenConfig, CanopenConfig(), given, prefix=PARAMETERS)
    deadline = max(config.receive_deadline_ms, CanopenConfig.receive_deadline_ms)
    return dataclasses.replace(config, period_us=1000, receive_deadline_ms=deadline)


def emulated_canopen(config: CanopenConfig, bench: BoardConfig) -> CanopenConfig:
    """``config`` for the emulated bench in lockstep: its EDS files unless given, its supply, SYNC by answer.

    Raises:
        ValueError: An interface the emulated bench cannot share with the master in this process.
    """
    if config.interface not in EMULATED_INTERFACES:
        raise ValueError(
            f"{parameter('interface')} {config.interface!r}: the emulated CANopen bench (--bench-file) runs "
            f"on {' or '.join(EMULATED_INTERFACES)}; a real bus is --board {EXTERNAL}"
        )
    return dataclasses.replace(
        config,
        valve_eds=config.valve_eds or str(eds_path("valve_cia408.eds")),
        encoder_eds=config.encoder_eds or str(eds_path("encoder_cia406.eds")),
        supply_bar=bench.supply_pressure,  # no node sends it: the bench's own is the stated value
        sync_clock=False,
        sync_on_enabled=False,
        heartbeat_ms=_LOCKSTEP_HEARTBEAT_MS,
        pdo_validity_ms=_LOCKSTEP_PDO_VALIDITY_MS,
    )


def external_canopen(config: CanopenConfig) -> CanopenConfig:
    """``config`` for a real bus: real time, the master sending each SYNC when due."""
    return dataclasses.replace(config, sync_clock=True, sync_on_enabled=False)


def open_bench(arguments: argparse.Namespace) -> Device:
    """The bench the arguments name, opened: ``--link``, ``--board`` or ``--bench-file``, ``--params-file``.

    Raises:
        BenchFileError: The bench file is invalid.
        DeviceError: The link cannot be opened (a ``ConfigureError``: a CANopen node missing or wrong).
        ValueError: A malformed address, an option that does not fit the link.
    """
    files: Sequence[Path] = arguments.params_file or ()
    if arguments.link == "canopen":
        settings = canopen_settings(files)
        if arguments.bench_file is not None:
            bench = load_bench_file(arguments.bench_file)
            device: Device = CanopenLockstepDevice(bench, emulated_canopen(settings, bench))
        elif arguments.board == EXTERNAL:
            link = LinkConfig(transport="canopen", configure_timeout=arguments.timeout)
            return open_device(link, external_canopen(settings), link_bridge("canopen"))
        else:
            raise ValueError(
                f"--link canopen takes --board {EXTERNAL} (a real bus, its canopen.* from --params-file) or "
                f"--bench-file FILE, not --board {arguments.board}"
            )
    elif files:
        raise ValueError("--params-file gives the CANopen link's canopen.*: only with --link canopen")
    elif arguments.bench_file is not None:
        device = LockstepDevice(load_bench_file(arguments.bench_file))
    else:
        board = parse_address(arguments.board)
        bind = parse_address(arguments.bind)
        link = LinkConfig(
            bind_address=bind[0], bind_port=bind[1], board_address=board[0], board_port=board[1]
        )
        device = udp_device(link, CanopenConfig(), BridgeConfig())
    device.open()
    return device
