"""The CANopen link's settings (the bridge's ``canopen.*`` parameters), without the bus libraries. No ROS."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Final

from smm_schema.ranges import bounds, check_bounds

from smm_hw_bridge.control_rate import CONTROL_RATES_HZ

__all__ = [
    "JOINTS",
    "PARAMETERS",
    "CanopenConfig",
    "bus_load",
    "frame_bits",
    "highest_rate_that_fits",
    "parameter",
]

JOINTS = ("alpha", "beta")
PARAMETERS: Final[str] = "canopen"
"""The prefix of the bridge's parameters of :class:`CanopenConfig` (``canopen.interface``, ...)."""


def parameter(name: str) -> str:
    """The bridge's parameter of :class:`CanopenConfig`'s field ``name`` (``canopen.<name>``)."""
    return f"{PARAMETERS}.{name}"


def _files(names: str) -> list[str]:
    """The comma-separated file names of ``names`` (none for "")."""
    return [name.strip() for name in names.split(",")] if names.strip() else []


@dataclass(frozen=True)
class CanopenConfig:
    """The CANopen link (``canopen.*`` parameters).

    Attributes:
        interface: python-can's interface (``socketcan``, ``pcan``, ``kvaser``, ``udp_multicast``, ...).
        channel: Its channel (``can0``; for ``udp_multicast`` an IPv4 group).
        bitrate: Bus bit rate (bit/s), used where the interface sets it.
        port: UDP port, where the interface takes one (``udp_multicast``).
        valve_node_ids: CiA 408 valve node ids (alpha, beta), in [1, 127].
        encoder_node_ids: CiA 406 encoder node ids (alpha, beta), in [1, 127].
        valve_eds: EDS / DCF file of the valves: one, or one per joint separated by a comma ("" refused
            at configure).
        encoder_eds: EDS / DCF file of the encoders: one, or one per joint separated by a comma.
        heartbeat_ms: Every node's heartbeat period (ms); consumers allow 3 periods.
        control_mode: The valves' control mode 0x6043 (2: spool position, closed loop).
        period_us: SYNC period written to 0x1006 (us): one a control period, 1000 x
            ``bridge.control_divider`` (another refused at configure).
        receive_deadline_ms: The valves' RPDO1 event timer 0x1400:05 (ms): no setpoint for that long and a
            valve faults by itself.
        bar_per_unit: The pressure scale: each valve's pressure actual 0x6381:01 (its joint's load
            pressure, bar) per unit, > 0; to the bridge's ``bridge.pressure.*`` as an A/D code.
        supply_bar: The supply pressure the bridge reports on this link (bar): no node sends it; a stated
            value, the bench's supply.
        master_node_id: The master's node id in the consumers' 0x1016 (its heartbeat's id), in [1, 127].
        sdo_timeout: SDO answer timeout (s).
        max_bus_load: The bus load refused at configure (fraction of the bit rate), in (0, 1].
        pdo_validity_ms: A SYNC's TPDOs not all arrived this long after it is a fault naming the nodes (ms).
        sync_on_enabled: Lockstep: a SYNC follows an enabled command, the first disabled one after it, and
            the opening, not the other disabled ones (the frame board's lockstep trigger ``enabled``: a
            run's steps are the controller's, none pass while it has not armed).
        sync_clock: Real time: the master sends the SYNC every ``period_us`` itself, from the loop's
            thread as it waits for feedback, not after each command (docs/HW_CANOPEN.md, "Real time").
    """

    interface: str = "udp_multicast"
    channel: str = "239.74.163.2"
    bitrate: int = field(default=1_000_000, metadata=bounds(10_000, 1_000_000))
    port: int = field(default=43113, metadata=bounds(1, 65535))
    valve_node_ids: tuple[int, int] = field(default=(1, 2), metadata=bounds(1, 127))
    encoder_node_ids: tuple[int, int] = field(default=(11, 12), metadata=bounds(1, 127))
    valve_eds: str = ""
    encoder_eds: str = ""
    heartbeat_ms: int = field(default=100, metadata=bounds(1, 65535))
    control_mode: int = field(default=2, metadata=bounds(1, 127))
    period_us: int = field(default=1000, metadata=bounds(100, 1_000_000))
    receive_deadline_ms: int = field(default=10, metadata=bounds(1, 65535))
    bar_per_unit: float = field(default=0.01, metadata=bounds(1e-9, 1e3))
    supply_bar: float = field(default=10.0, metadata=bounds(0.0, 1e3))
    master_node_id: int = field(default=127, metadata=bounds(1, 127))
    sdo_timeout: float = field(default=0.5, metadata=bounds(0.001, 60.0))
    max_bus_load: float = field(default=0.7, metadata=bounds(1e-3, 1.0))
    pdo_validity_ms: int = field(default=100, metadata=bounds(1, 600_000))
    sync_on_enabled: bool = False
    sync_clock: bool = False

    def __post_init__(self) -> None:
        check_bounds(self)
        ids = (*self.valve_node_ids, *self.encoder_node_ids, self.master_node_id)
        if len(set(ids)) != len(ids):
            raise ValueError(f"node ids must differ (valves, encoders, master), got {ids}")
        for name in ("valve_eds", "encoder_eds"):
            if len(_files(getattr(self, name))) not in (0, 1, len(JOINTS)):  # none: refused at configure
                raise ValueError(
                    f"{name} must name one EDS file or one per joint, got {getattr(self, name)!r}"
                )
        if self.receive_deadline_ms * 1000 <= self.period_us:
            raise ValueError(
                f"receive_deadline_ms ({self.receive_deadline_ms} ms) must be longer than the SYNC period "
                f"period_us ({self.period_us} us): a valve would fault between two setpoints on time"
            )
        if self.sync_clock and self.sync_on_enabled:
            raise ValueError("sync_clock (real time) and sync_on_enabled (lockstep) exclude each other")
        if not all(math.isfinite(value) for value in (self.bar_per_unit, self.supply_bar)):
            raise ValueError("bar_per_unit and supply_bar must be finite")

    def eds(self, kind: str, joint: int) -> str:
        """The EDS file of the ``kind`` (``valve``, ``encoder``) node of ``joint``."""
        files = _files(self.valve_eds if kind == "valve" else self.encoder_eds)
        return files[joint] if len(files) > 1 else files[0]


def frame_bits(data_bytes: int) -> int:
    """Bits of one standard CAN frame with ``data_bytes`` bytes, worst-case bit stuffing included."""
    return 44 + 8 * data_bytes + (34 + 8 * data_bytes - 1) // 4


def bus_load(payloads: list[int], rate_hz: float, bitrate: int) -> float:
    """The bus's load (fraction) of frames of ``payloads`` bytes each cycle, ``rate_hz`` cycles a second."""
    return sum(frame_bits(size) for size in payloads) * rate_hz / bitrate


def highest_rate_that_fits(payloads: list[int], bitrate: int, limit: float) -> int | None:
    """The highest offered control rate (Hz) whose load stays within ``limit``, None if none."""
    return next((rate for rate in CONTROL_RATES_HZ if bus_load(payloads, rate, bitrate) <= limit), None)
