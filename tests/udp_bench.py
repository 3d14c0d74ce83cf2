"""Shared by the bridge and emulator tests: free loopback ports, the rejections counted before admission, a
feedback frame made by hand, a command answering one."""

import socket

from smm_hw_bridge.core import BridgeCore
from smm_hw_bridge.protocol import CommandFlag, CommandFrame, FeedbackFrame, Reason

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


def feedback_frame(session: int, seq: int, tick: int, **fields: object) -> FeedbackFrame:
    """A valid feedback frame: no host, counts 0, supply A/D 1638, nothing applied; ``fields`` change it."""
    values: dict[str, object] = {
        "host_session": 0,
        "counts": (0, 0),
        "adc": (1638, 2048, 2048, 2048),
        "status": 0,
        "faults": 0,
        "applied_seq": 0,
        "applied_age": 0xFFFF,
        "output_codes": (0, 0),
        "late_commands": 0,
        "crc_errors": 0,
        "dropped_frames": 0,
        **fields,
    }
    return FeedbackFrame(session=session, seq=seq, tick=tick, **values)  # type: ignore[arg-type]


def answer(
    feedback: FeedbackFrame,
    seq: int,
    codes: tuple[int, int],
    flags: int = int(CommandFlag.ENABLE),
    session: int = 7,
) -> CommandFrame:
    """A command frame answering ``feedback`` (validity 10 ticks), from host ``session``."""
    return CommandFrame(
        session=session,
        seq=seq,
        board_session=feedback.session,
        answers_seq=feedback.seq,
        answers_tick=feedback.tick,
        flags=flags,
        validity=10,
        codes=codes,
    )
