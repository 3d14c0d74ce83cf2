"""Configuring the CANopen link: the settings checked against the bridge's, each node checked and set by SDO.

Device type, identity and PDO mapping against the user's EDS read; device mode, control mode, cycle
period, heartbeats and the valves' receive deadline written; the cycle's bus load checked. A refusal names
the node and the object (docs/HW_CANOPEN.md, "Objects used"). No ROS.
"""

from __future__ import annotations

import logging
import time
from typing import Final

import canopen
from canopen.sdo import SdoAbortedError, SdoCommunicationError
from canopen.sdo.constants import ABORT_TIMED_OUT

from smm_hw_bridge.bridge_config import BridgeConfig
from smm_hw_bridge.canopen_config import JOINTS, CanopenConfig, bus_load, highest_rate_that_fits, parameter
from smm_hw_bridge.canopen_node import CanNode
from smm_hw_bridge.cia408 import (
    CONTROL_MODE,
    CONTROL_WORD,
    DEVICE_MODE,
    DEVICE_MODE_BUS,
    DEVICE_TYPE,
    POSITION,
    PRESSURE_ACTUAL,
    PROFILE_ENCODER,
    PROFILE_VALVE,
    SPOOL_ACTUAL,
    SPOOL_FULL_SCALE,
    SPOOL_SETPOINT,
    STATUS_WORD,
    ValveState,
    control_word,
)
from smm_hw_bridge.control_rate import BOARD_TICK_HZ, MAX_DIVIDER
from smm_hw_bridge.device import DeviceError

__all__ = [
    "CONTROL_DIVIDER",
    "ConfigureError",
    "await_answer",
    "check_bridge",
    "check_bus_load",
    "configure_node",
    "remote_node",
]

CONTROL_DIVIDER: Final[str] = "bridge.control_divider"
"""The bridge's parameter the SYNC period must match (:func:`check_bridge`)."""
_TICK_US: Final[int] = 1_000_000 // BOARD_TICK_HZ
_IDENTITY: Final[int] = 0x1018
_CYCLE_PERIOD: Final[int] = 0x1006
_HEARTBEAT_CONSUMER: Final[int] = 0x1016
_HEARTBEAT_PRODUCER: Final[int] = 0x1017
_RPDO1_COMM: Final[int] = 0x1400
_RPDO1_MAP: Final[int] = 0x1600
_TPDO1_MAP: Final[int] = 0x1A00
_EVENT_TIMER: Final[int] = 5


class _TimeoutAbortFilter(logging.Filter):
    """Drops the SDO client's log line of its own abort on a timeout (the raw code 0x05040000).

    Every SDO timeout raises ``SdoCommunicationError``, which the master states in words naming the node
    and the object; the library's line would only repeat it as a code (and python's last-resort handler
    prints it on stderr, once a try while waiting for a bench to boot).
    """

    def filter(self, record: logging.LogRecord) -> bool:
        """False for the abort-on-timeout line, True for every other."""
        return record.getMessage() != f"Transfer aborted by client with code 0x{ABORT_TIMED_OUT:08X}"


logging.getLogger("canopen.sdo.client").addFilter(_TimeoutAbortFilter())


class ConfigureError(DeviceError):
    """A node refused at configure: missing, of the wrong profile, or its objects not as its EDS says."""


def check_bridge(config: CanopenConfig, bridge: BridgeConfig) -> None:
    """Refuses, before any bus traffic, a code limit beyond full spool or a SYNC period not the control one.

    Raises:
        ConfigureError: The reason, naming the parameters and the value that would fit.
    """
    limit = bridge.valve.code_limit
    if any(code > SPOOL_FULL_SCALE for code in limit):
        raise ConfigureError(
            f"bridge.valve.code_limit {list(limit)} is above the valves' full scale {SPOOL_FULL_SCALE} "
            f"(100 % spool, 0x6300:01) on the CANopen link: set it to at most {SPOOL_FULL_SCALE}"
        )
    divider = bridge.control_divider
    if config.period_us != _TICK_US * divider:
        fits, other = _TICK_US * divider, ""
        if config.period_us % _TICK_US == 0 and 1 <= config.period_us // _TICK_US <= MAX_DIVIDER:
            other = f" (or {CONTROL_DIVIDER} to {config.period_us // _TICK_US})"
        raise ConfigureError(
            f"{parameter('period_us')} {config.period_us} us does not match {CONTROL_DIVIDER} {divider}: "
            f"one SYNC a control period is {_TICK_US} x {CONTROL_DIVIDER} us; set {parameter('period_us')} "
            f"to {fits}{other}"
        )
    if not config.valve_eds or not config.encoder_eds:
        raise ConfigureError(
            f"{parameter('valve_eds')} and {parameter('encoder_eds')} must name the devices' EDS files"
        )


def remote_node(config: CanopenConfig, kind: str, joint: int, node_id: int) -> CanNode:
    """The ``kind`` node of ``joint`` as its EDS describes it, its PDOs as the EDS maps them.

    Raises:
        ConfigureError: Its EDS cannot be read.
    """
    path = config.eds(kind, joint)
    try:
        remote = canopen.RemoteNode(node_id, path)
    except (OSError, ValueError, KeyError) as error:
        raise ConfigureError(
            f"{kind} {JOINTS[joint]} (node {node_id}): cannot read EDS {path}: {error}"
        ) from error
    remote.sdo.RESPONSE_TIMEOUT = config.sdo_timeout
    return CanNode(kind, joint, remote)


def await_answer(node: CanNode, deadline: float) -> None:
    """Until ``deadline`` (monotonic s): asks ``node`` its device type until it answers at all."""
    while time.monotonic() < deadline:
        try:
            node.remote.sdo.upload(DEVICE_TYPE, 0)
        except SdoCommunicationError:
            continue  # not up yet; past the deadline, configure_node names it
        except SdoAbortedError:
            return
        return


def _upload(node: CanNode, index: int, subindex: int = 0) -> int:
    try:
        data = node.remote.sdo.upload(index, subindex)
    except SdoCommunicationError as error:
        raise ConfigureError(
            f"{node.name}: no answer to reading 0x{index:04X}:{subindex:02X} ({error})"
        ) from error
    except SdoAbortedError as error:
        raise ConfigureError(
            f"{node.name}: reading 0x{index:04X}:{subindex:02X} refused ({error})"
        ) from error
    return int.from_bytes(data[:4], "little")


def _download(node: CanNode, index: int, subindex: int, value: int, size: int) -> None:
    try:
        node.remote.sdo.download(index, subindex, value.to_bytes(size, "little", signed=value < 0))
    except (SdoCommunicationError, SdoAbortedError) as error:
        raise ConfigureError(
            f"{node.name}: writing 0x{index:04X}:{subindex:02X} = {value} refused ({error})"
        ) from error


def configure_node(node: CanNode, config: CanopenConfig) -> None:
    """Reads and checks ``node``'s device type, identity and PDO mappings; writes its settings.

    Raises:
        ConfigureError: No answer, a refused access, a wrong profile or identity, a mapping not its EDS's.
    """
    node.device_type = _upload(node, DEVICE_TYPE)
    profile = PROFILE_VALVE if node.kind == "valve" else PROFILE_ENCODER
    if node.device_type & 0xFFFF != profile:
        raise ConfigureError(
            f"{node.name}: device type 0x1000 = 0x{node.device_type:08X}, "
            f"profile {node.device_type & 0xFFFF}, "
            f"not CiA {profile}"
        )
    node.identity = tuple(_upload(node, _IDENTITY, sub) for sub in (1, 2, 3, 4))  # type: ignore[assignment]
    _check_identity(node, config)
    if node.kind == "valve":
        _check_mapping(
            node, _TPDO1_MAP, node.remote.tpdo[1], (STATUS_WORD, SPOOL_ACTUAL[0], PRESSURE_ACTUAL[0])
        )
        _check_mapping(node, _RPDO1_MAP, node.remote.rpdo[1], (CONTROL_WORD, SPOOL_SETPOINT[0]))
    else:
        _check_mapping(node, _TPDO1_MAP, node.remote.tpdo[1], (POSITION,))
    if node.kind == "valve":
        _download(node, DEVICE_MODE, 0, DEVICE_MODE_BUS, 1)
        _download(node, CONTROL_MODE, 0, config.control_mode, 1)
        _download(node, _RPDO1_COMM, _EVENT_TIMER, config.receive_deadline_ms, 2)
        _download(node, CONTROL_WORD, 0, control_word(ValveState.DISABLED), 2)
    _download(node, _CYCLE_PERIOD, 0, config.period_us, 4)
    _download(node, _HEARTBEAT_PRODUCER, 0, config.heartbeat_ms, 2)
    consumer = (config.master_node_id << 16) | min(3 * config.heartbeat_ms, 0xFFFF)
    _download(node, _HEARTBEAT_CONSUMER, 1, consumer, 4)


def _check_identity(node: CanNode, config: CanopenConfig) -> None:
    """Refuses a vendor-ID or product code (0x1018:01, :02) other than its EDS's 0x1018 says."""
    od = node.remote.object_dictionary
    for sub, what in ((1, "vendor-ID"), (2, "product code")):
        try:
            expected = int(od[_IDENTITY][sub].default)
        except (KeyError, TypeError, ValueError):
            continue  # the EDS does not say: nothing to compare
        found = node.identity[sub - 1]
        if found != expected:
            raise ConfigureError(
                f"{node.name}: identity 0x1018:{sub:02X} ({what}) = 0x{found:08X}, its EDS "
                f"{config.eds(node.kind, node.joint)} says 0x{expected:08X}: another device"
            )


def _check_mapping(node: CanNode, index: int, pdo: canopen.pdo.PdoMap, needed: tuple[int, ...]) -> None:
    od = node.remote.object_dictionary
    if index not in od:
        raise ConfigureError(f"{node.name}: its EDS has no 0x{index:04X} (PDO mapping)")
    mapped = {variable.index for variable in pdo}
    missing = [f"0x{object_index:04X}" for object_index in needed if object_index not in mapped]
    if missing:
        raise ConfigureError(f"{node.name}: its EDS's PDO mapping 0x{index:04X} lacks {', '.join(missing)}")
    record = od[index]
    expected = [int(record[sub].default) for sub in range(1, int(record[0].default) + 1)]
    found_count = _upload(node, index, 0) & 0xFF
    found = [_upload(node, index, sub) for sub in range(1, found_count + 1)]
    if found != expected:
        raise ConfigureError(
            f"{node.name}: PDO mapping 0x{index:04X} on the device is "
            f"{[f'0x{v:08X}' for v in found]}, its EDS says {[f'0x{v:08X}' for v in expected]}"
        )


def check_bus_load(config: CanopenConfig, nodes: list[CanNode]) -> None:
    """Refuses a cycle (SYNC, valve RPDO1s, every TPDO1, as the EDS files map them) above the limit.

    Raises:
        ConfigureError: The load, and the highest offered rate that fits.
    """
    payloads = [1 if config.sync_clock else 0]  # the SYNC (its counter in real time)
    for node in nodes:
        payloads.append(len(node.remote.tpdo[1].data))
        if node.kind == "valve":
            payloads.append(len(node.remote.rpdo[1].data))
    rate = 1e6 / config.period_us
    load = bus_load(payloads, rate, config.bitrate)
    if load > config.max_bus_load:
        fits = highest_rate_that_fits(payloads, config.bitrate, config.max_bus_load)
        raise ConfigureError(
            f"bus load {100 * load:.1f} % at {rate:g} Hz and {config.bitrate} bit/s (frames of "
            f"{payloads} bytes a cycle, worst-case stuffing) is above {parameter('max_bus_load')} "
            f"{100 * config.max_bus_load:g} %; "
            + (f"the highest offered rate that fits is {fits} Hz" if fits else "no offered rate fits")
        )
