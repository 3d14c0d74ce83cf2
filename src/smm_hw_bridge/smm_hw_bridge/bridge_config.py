"""The bridge logic's configuration: encoder, valve, admission, pressure, safety stop, watchdogs, rate."""

from __future__ import annotations

from dataclasses import dataclass, field

from smm_schema.ranges import above, bounds, check_bounds

from smm_hw_bridge.control_rate import MAX_DIVIDER, held_ticks, in_flight_ticks
from smm_hw_bridge.encoder import EncoderConfig
from smm_hw_bridge.link import AdmissionConfig
from smm_hw_bridge.pressure import PressureConfig
from smm_hw_bridge.safety_stop import SafetyStopConfig
from smm_hw_bridge.valve_output import ValveOutputConfig

__all__ = ["BridgeConfig"]


@dataclass(frozen=True)
class BridgeConfig:
    """Everything the bridge logic needs.

    Attributes:
        encoder: Counts -> rad.
        valve: Torque -> D/A code.
        admission: Feedback admission (tick period, staleness).
        pressure: Load-pressure transducers (A/D channels 1, 2) -> the measured joint torque.
        host_watchdog_ns: No fresh command for this long -> safe output (ns), > 0; at a divider N the
            bridge waits 2 (N - 1) ticks longer (:attr:`watchdog_ns`).
        stale_periods: A command answering a measurement more than this many ticks older than the newest
            is refused (K), >= 1; at a divider N, N - 1 ticks more (:attr:`stale_ticks`).
        validity_ticks: Ticks after the answered measurement during which the board may apply a command,
            in [1, 65535], as at 1 kHz control; at a divider N the frames carry 2 (N - 1) ticks more
            (:attr:`validity`; docs/LAUNCH.md, "Control rate").
        control_divider: N, board ticks per control period, in [1, 10]: the host answers the feedback of
            board ticks that are multiples of N and the board holds each command in between.
        soft_limits: Joint soft limits +-limit (alpha, beta) (rad), > 0: beyond one, a torque that drives
            further out is cut to 0; one that drives back is passed.
        limit_stop: When a run is a safety stop (:meth:`BridgeCore.limit_stop`: host fault, safe output):
            the cut above cannot hold a joint whose valve or encoder runs the other way than the bridge
            assumes.
        link_timeout_ns: No admitted feedback for this long -> link down (ns), > 0.
        reboot_frames: Consecutive frames of one new board session that mean the board restarted, >= 1.
        supply_bar_per_code: Supply pressure per A/D code of channel 0 (bar), > 0.
        lockstep: The board ticks only when an enabled command answers its last feedback (the emulator's
            lockstep): activation then accepts a command answering the current measurement, which stays
            current until the output is live.
    """

    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    valve: ValveOutputConfig = field(default_factory=ValveOutputConfig)
    admission: AdmissionConfig = field(default_factory=AdmissionConfig)
    pressure: PressureConfig = field(default_factory=PressureConfig)
    host_watchdog_ns: int = field(default=10_000_000, metadata=bounds(1, 10_000_000_000))
    stale_periods: int = field(default=5, metadata=bounds(1, 65535))
    validity_ticks: int = field(default=10, metadata=bounds(1, 65535))
    control_divider: int = field(default=1, metadata=bounds(1, MAX_DIVIDER))
    soft_limits: tuple[float, float] = field(default=(1.2, 1.2), metadata=above(0.0))
    limit_stop: SafetyStopConfig = field(default_factory=SafetyStopConfig)
    link_timeout_ns: int = field(default=100_000_000, metadata=bounds(1, 60_000_000_000))
    reboot_frames: int = field(default=3, metadata=bounds(1, 1000))
    supply_bar_per_code: float = field(default=25.0 / 4095.0, metadata=bounds(1e-9, 1e3))
    lockstep: bool = False

    def __post_init__(self) -> None:
        for name, kind in (
            ("encoder", EncoderConfig),
            ("valve", ValveOutputConfig),
            ("admission", AdmissionConfig),
            ("pressure", PressureConfig),
            ("limit_stop", SafetyStopConfig),
        ):
            if not isinstance(getattr(self, name), kind):
                raise ValueError(f"{name} must be a {kind.__name__}, got {getattr(self, name)!r}")
        check_bounds(self)
        if self.validity > 0xFFFF:
            raise ValueError(
                f"validity_ticks must be <= {0xFFFF - held_ticks(self.control_divider)} at control_divider "
                f"{self.control_divider} (a u16 on the wire), got {self.validity_ticks!r}"
            )
        if not isinstance(self.lockstep, bool):
            raise ValueError(f"lockstep must be a bool, got {self.lockstep!r}")

    @property
    def period_ns(self) -> int:
        """Board tick period (ns)."""
        return self.admission.period_ns

    @property
    def validity(self) -> int:
        """The validity every command frame carries (ticks): ``validity_ticks`` + 2 (N - 1)."""
        return self.validity_ticks + held_ticks(self.control_divider)

    @property
    def stale_ticks(self) -> int:
        """A command answering a measurement more than this many ticks older than the newest is refused."""
        return self.stale_periods + in_flight_ticks(self.control_divider)

    @property
    def watchdog_ns(self) -> int:
        """No fresh command for this long -> safe output (ns): ``host_watchdog_ns`` + 2 (N - 1) ticks."""
        return self.host_watchdog_ns + held_ticks(self.control_divider) * self.period_ns
