"""The emulated bench in this process, in lockstep: the emulator's board, or the emulated CANopen bench.

A :class:`Device` over the board (seeded), or the bridge's CANopen master over the CANopen bench. Each
command answering the last feedback ticks the board once (on CANopen: its SYNC steps the bench once), so a
step's run is the same on any machine.
"""

from __future__ import annotations

from typing import Final

import can
from smm_bench_emulator.board import BoardConfig, BoardCore
from smm_bench_emulator.canopen_bench import CanBench, CanBenchConfig
from smm_hw_bridge.can_multicast import MulticastRouteError, loopback_multicast_bus
from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.canopen_device import CanopenDevice
from smm_hw_bridge.device import Device, DeviceDescription, DeviceError, Reading, ValveCommand
from smm_hw_bridge.protocol import ADC_CHANNELS, FeedbackFrame, ProtocolError, decode_feedback, encode

from smm_commissioning.host import link_bridge

__all__ = ["EMULATED_INTERFACES", "CanopenLockstepDevice", "LockstepDevice"]

EMULATED_INTERFACES: Final[tuple[str, ...]] = ("udp_multicast", "virtual")
"""python-can interfaces the emulated CANopen bench shares with the master in this process: the loopback
multicast group (refused unless it routes over ``lo``), or python-can's in-process bus."""


class LockstepDevice(Device):
    """The board of ``config`` behind an in-memory link, ticked by each command that answers its feedback.

    Args:
        config: The emulated bench (``smm_bench_emulator --bench-file``'s description).
    """

    def __init__(self, config: BoardConfig) -> None:
        super().__init__()
        self.description = DeviceDescription(
            name="lockstep",
            joints=("alpha", "beta"),
            valves=("alpha", "beta"),
            analog=("supply", *(f"spare{index}" for index in range(1, ADC_CHANNELS))),
            own_watchdog=True,
            validity=True,
        )
        self.board = BoardCore(config)
        self._queue: list[bytes] | None = None
        self.peak = [0.0, 0.0]
        """Largest |q| each joint reached (rad), the truth a test checks against the stops."""

    def open(self) -> None:
        """Boots the board (once): its first feedback waits to be read."""
        if self._queue is None:
            self._queue = [self.board.start()]

    def close(self) -> None:
        """Nothing to release."""

    def read(self, timeout_s: float) -> Reading | None:
        """The next feedback (None when the board waits for an answer)."""
        if self._queue is None:
            raise DeviceError("the device is not open")
        if not self._queue:
            return None
        try:
            return decode_feedback(self._queue.pop(0))
        except ProtocolError as error:  # pragma: no cover - the board encodes what it checked
            return error.reason

    def write(self, command: ValveCommand) -> None:
        """Hands the command to the board; one that answers its last feedback ticks it."""
        if self._queue is None:
            raise DeviceError("the device is not open")
        self.board.receive(encode(command))
        if self.board.answered:
            self._queue.append(self.board.tick_lockstep())
            for joint, angle in enumerate(self.board.plant.state_floats[:2]):
                self.peak[joint] = max(self.peak[joint], abs(angle))

    def make_safe(self) -> None:
        """Nothing beyond the disabled frames: the board holds the joints."""


class CanopenLockstepDevice(CanopenDevice):
    """The bridge's CANopen master over the emulated CANopen bench of ``board``, both in this process.

    Each answer is one SYNC, one bench cycle (``config.sync_on_enabled`` false, ``sync_clock`` false). The
    pressure actuals carry the bench's A/D noise in bar (a transducer's noise: a stuck one shows).

    Args:
        board: The emulated bench (``--bench-file``).
        config: The link (:func:`smm_commissioning.link.emulated_canopen`): the bench's nodes, its bus.
    """

    def __init__(self, board: BoardConfig, config: CanopenConfig) -> None:
        super().__init__(config, bridge=link_bridge("canopen"))
        noise = board.adc_noise * sum(board.load_bar_per_code) / 2.0
        self.bench_config = CanBenchConfig(
            board=board,
            valve_node_ids=config.valve_node_ids,
            encoder_node_ids=config.encoder_node_ids,
            bar_per_unit=config.bar_per_unit,
            pressure_noise=noise,
        )
        self.bench: CanBench | None = None
        """The emulated bench (kept after :meth:`close`: its valves' last states)."""
        self._running = False
        self.peak = [0.0, 0.0]
        """Largest |q| each joint reached (rad), the truth a test checks against the stops."""

    def open(self) -> None:
        """Starts the emulated bench on the bus, then configures and starts its nodes as the master."""
        if self.network is not None:
            return
        config = self.config
        try:
            if config.interface == "udp_multicast":
                bus = loopback_multicast_bus(config.channel, config.port)
            else:
                bus = can.Bus(interface=config.interface, channel=config.channel)
        except (can.CanError, OSError, ValueError, MulticastRouteError) as error:
            raise DeviceError(
                f"cannot open CAN interface {config.interface} {config.channel} for the emulated bench: "
                f"{error}"
            ) from error
        self.bench = CanBench(self.bench_config, bus)
        self._running = True
        try:
            super().open()
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Leaves the bus as the master, then stops the emulated bench (idempotent)."""
        super().close()
        if self._running and self.bench is not None:
            self._running = False
            self.bench.close()

    def read(self, timeout_s: float) -> Reading | None:
        """The master's feedback; the joints' largest excursion noted."""
        reading = super().read(timeout_s)
        if isinstance(reading, FeedbackFrame) and self.bench is not None:
            with self.bench.lock:
                angles = self.bench.board.plant.state_floats[:2]
            for joint, angle in enumerate(angles):
                self.peak[joint] = max(self.peak[joint], abs(angle))
        return reading
