"""The emulated bench in this process, in lockstep: a :class:`Device` over the emulator's board (seeded).

Each command answering the last feedback ticks the board once, so a step's run is the same on any machine.
"""

from __future__ import annotations

from smm_bench_emulator.board import BoardConfig, BoardCore
from smm_hw_bridge.device import Device, DeviceDescription, DeviceError, Reading, ValveCommand
from smm_hw_bridge.protocol import ADC_CHANNELS, ProtocolError, decode_feedback, encode

__all__ = ["LockstepDevice"]


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
