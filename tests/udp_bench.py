"""Shared by the bridge and emulator tests: free loopback ports, the rejections counted before admission."""

import socket

from smm_hw_bridge.core import BridgeCore
from smm_hw_bridge.protocol import Reason

LOOPBACK = "127.0.0.1"

#: Frames the parser refuses, and feedback from a board session that is not ours (never admitted).
PARSE_AND_SESSION_REASONS = (
    Reason.CRC,
    Reason.MAGIC,
    Reason.LENGTH,
    Reason.VERSION,
    Reason.TYPE,
    Reason.FIELD,
    Reason.SESSION,
)


def free_port() -> int:
    """A UDP port on loopback that nothing is bound to now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((LOOPBACK, 0))
        return int(sock.getsockname()[1])


def parse_and_session_rejections(core: BridgeCore) -> int:
    """Frames ``core`` refused before admission, all reasons of :data:`PARSE_AND_SESSION_REASONS` together."""
    return sum(core.rejected.get(reason, 0) for reason in PARSE_AND_SESSION_REASONS)
