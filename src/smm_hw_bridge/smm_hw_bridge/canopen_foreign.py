"""Another master on the bus: data frames on the COB-IDs only this master sends (NMT, SYNC, RPDO, SDO).

Any such frame not this master's own is another master's (a fault, docs/HW_CANOPEN.md, "Faults"). No ROS.
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable
from typing import Final

import can

from smm_hw_bridge.canopen_node import CanNode

__all__ = ["NMT_ID", "SDO_REQUEST", "SYNC_ID", "ForeignListener", "foreign_message"]

NMT_ID: Final[int] = 0x000
SYNC_ID: Final[int] = 0x080
SDO_REQUEST: Final[int] = 0x600
"""COB-ID of a node's SDO requests, plus its node id."""


def foreign_message(can_id: int, data: bytes) -> str:
    """The fault's words for another master's frame ``can_id`` carrying ``data``."""
    what = {NMT_ID: "NMT command", SYNC_ID: "SYNC"}.get(can_id, "frame")
    return f"{what} 0x{can_id:03X} [{data.hex(' ')}] from another master"


class ForeignListener(can.Listener):
    """Hands the data frames on the master's own COB-IDs (sent by another) to ``handle``.

    ``ids``: those COB-IDs and the node each addresses (None: the whole bus). ``echoes``: the bus hands the
    master its own frames back (python-can's ``udp_multicast``): each frame sent on those COB-IDs is
    expected back once, in order, and is not another's.
    """

    def __init__(
        self,
        handle: Callable[[CanNode | None, int, bytearray], None],
        ids: dict[int, CanNode | None],
        bus: can.BusABC,
        echoes: bool,
    ):
        self._handle, self._ids = handle, ids
        self._sent: dict[int, collections.deque[bytes]] = {}
        self._guard = threading.Lock()
        if echoes:
            send = bus.send

            def sending(msg: can.Message, timeout: float | None = None) -> None:
                if msg.arbitration_id in self._ids:
                    with self._guard:
                        self._sent.setdefault(msg.arbitration_id, collections.deque(maxlen=64)).append(
                            bytes(msg.data)
                        )
                send(msg, timeout)

            bus.send = sending  # type: ignore[method-assign]

    def on_message_received(self, msg: can.Message) -> None:
        """A frame from the bus (the notifier's thread): another's on those COB-IDs to ``handle``."""
        if msg.is_error_frame or msg.is_remote_frame or msg.arbitration_id not in self._ids:
            return
        with self._guard:
            sent = self._sent.get(msg.arbitration_id)
            if sent and sent[0] == bytes(msg.data):
                sent.popleft()  # our own, echoed
                return
        self._handle(self._ids[msg.arbitration_id], msg.arbitration_id, msg.data)

    def stop(self) -> None:
        """Nothing to release."""
