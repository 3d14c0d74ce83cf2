"""The emulator's board behind an in-memory link, for the bridge loop's tests (no socket, no ROS)."""

from __future__ import annotations

from smm_bench_emulator.board import BoardConfig, BoardCore
from smm_hw_bridge.transport import Transport


class MemoryBoard(Transport):
    """The emulator's board behind an in-memory link: feedback waits in a queue until read."""

    def __init__(self, config: BoardConfig | None = None) -> None:
        super().__init__()
        self.board = BoardCore(config if config is not None else BoardConfig())
        self.queue: list[bytes] = [self.board.start()]
        self.sent: list[bytes] = []

    def tick(self) -> None:
        self.queue.append(self.board.tick_realtime())

    def send(self, frame: bytes) -> None:
        self.sent.append(frame)
        self.board.receive(frame)

    def receive(self, timeout_s: float = 0.0) -> bytes | None:
        return self.queue.pop(0) if self.queue else None

    def fileno(self) -> int:
        return -1

    def close(self) -> None:
        pass
