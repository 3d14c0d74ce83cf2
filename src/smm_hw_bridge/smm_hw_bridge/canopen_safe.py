"""The CANopen valves told DISABLED by SDO at the end, every valve at once and bounded; in words, who was not.

A valve not told still stops by itself (its receive deadline and heartbeat consumer): docs/HW_CANOPEN.md,
"The valve's state machine". No ROS.
"""

from __future__ import annotations

import threading
import time
from typing import Final

import can
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.canopen_node import CanNode
from smm_hw_bridge.cia408 import CONTROL_WORD, ValveState, control_word

__all__ = ["tell_disabled", "untold_line"]

_JOIN_S: Final[float] = 0.1
"""How long (s) past the SDO timeout :func:`tell_disabled` waits for a write's own timeout."""


def tell_disabled(valves: list[CanNode], config: CanopenConfig) -> dict[str, str]:
    """Writes DISABLED to each valve's control word 0x6040 by SDO, all at once; why not, by valve name.

    A valve whose heartbeat is lost (none for 3 x ``heartbeat_ms``) is not asked; the others are waited for
    one ``sdo_timeout`` at most (each write in a thread of its own).
    """
    now, consumer_s = time.monotonic(), 3 * config.heartbeat_ms / 1000.0
    untold: dict[str, str] = {}
    asked: list[tuple[CanNode, threading.Thread]] = []
    for node in valves:
        if now - node.heard > consumer_s:
            untold[node.name] = f"its heartbeat lost for {now - node.heard:.1f} s: not asked"
            continue
        thread = threading.Thread(target=_tell, args=(node, untold), name="sdo_disabled", daemon=True)
        thread.start()
        asked.append((node, thread))
    deadline = now + config.sdo_timeout + _JOIN_S
    for node, thread in asked:
        thread.join(max(deadline - time.monotonic(), 0.0))
        if thread.is_alive():
            untold[node.name] = f"no answer within {config.sdo_timeout:g} s"
    return untold


def _tell(node: CanNode, untold: dict[str, str]) -> None:
    """One valve's SDO write of DISABLED; why it failed into ``untold`` (its own thread: never raises)."""
    try:
        node.remote.sdo.download(CONTROL_WORD, 0, control_word(ValveState.DISABLED).to_bytes(2, "little"))
    except SdoCommunicationError:
        untold[node.name] = f"no answer within {node.remote.sdo.RESPONSE_TIMEOUT:g} s"
    except SdoAbortedError as error:
        untold[node.name] = f"refused: {error}"
    except (can.CanError, OSError) as error:  # the bus closed under a write that outlived its wait
        untold[node.name] = f"the bus failed: {error}"


def untold_line(valves: list[CanNode], untold: dict[str, str], config: CanopenConfig) -> str:
    """One line for the log: the ``valves`` not told (in order, each with why) and what stops them."""
    named = ", ".join(f"{node.name} ({untold[node.name]})" for node in valves if node.name in untold)
    return (
        f"could not tell {named} DISABLED by SDO (0x6040); each valve goes to its failsafe by itself: "
        f"its receive deadline 0x1400:05 ({config.receive_deadline_ms} ms) once its setpoints stop, its "
        f"heartbeat consumer 0x1016 ({3 * config.heartbeat_ms} ms) once the master's heartbeat stops"
    )
