"""The CPUs' idle states during a real-time run: hold ``/dev/cpu_dma_latency`` at 0, and say what is set.

A CPU that sleeps in a deep idle state between two board ticks takes that state's exit latency to wake for
the next feedback frame; the kernel's PM QoS keeps every CPU out of states slower to leave than the lowest
latency any open file of ``/dev/cpu_dma_latency`` asks for, for as long as that file stays open. Why it
matters and the figures: docs/LAUNCH.md, "Idle states".
"""

from __future__ import annotations

import errno
import os
import struct
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Final

__all__ = [
    "CPU_DMA_LATENCY",
    "CPU_IDLE",
    "NO_LIMIT_US",
    "IdleStateHold",
    "IdleStates",
    "hold_idle_states",
    "read_idle_states",
]

CPU_DMA_LATENCY: Final[Path] = Path("/dev/cpu_dma_latency")
"""The kernel's machine-wide CPU wake-up latency request (PM QoS): a 32-bit limit in us."""
CPU_IDLE: Final[Path] = Path("/sys/devices/system/cpu/cpu0/cpuidle")
"""cpu0's idle states (``stateN/name``, ``stateN/latency`` in us)."""
NO_LIMIT_US: Final[int] = 2_000_000_000
"""The limit when nobody asks for one (``PM_QOS_CPU_LATENCY_DEFAULT_VALUE``): every idle state allowed."""
GRANT: Final[str] = (
    "run smm-launch as root, or let its user write the device: a udev rule "
    '(KERNEL=="cpu_dma_latency", GROUP="realtime", MODE="0660") with the user in that group, or '
    "`sudo chmod 0666 /dev/cpu_dma_latency` until the next boot"
)
"""How to let a run hold the limit."""

Opener = Callable[[str, int], int]


@dataclass(frozen=True)
class IdleStates:
    """What the CPUs may do between two ticks now.

    Attributes:
        limit_us: The machine-wide wake-up latency limit (us); None when it could not be read.
        states: cpu0's idle states as (name, exit latency in us), shallowest first; () when none listed.
        unread: Why the limit could not be read ("" when it was).
    """

    limit_us: int | None
    states: tuple[tuple[str, int], ...] = ()
    unread: str = ""

    @property
    def held(self) -> bool:
        """True when no idle state slower to leave than the fastest one is allowed (the limit below it)."""
        if self.limit_us is None:
            return False
        slower = [latency for _, latency in self.states if latency > 0]
        return self.limit_us == 0 or (bool(slower) and self.limit_us < min(slower))

    def statement(self) -> str:
        """One line: the limit, what it allows, cpu0's states with their exit latencies."""
        if self.limit_us is None:
            limit = f"limit unknown ({self.unread})"
        elif self.limit_us >= NO_LIMIT_US:
            limit = "no limit (every idle state allowed)"
        else:
            limit = f"limit {self.limit_us} us" + (
                " (held: CPUs stay awake between ticks)" if self.held else ""
            )
        listed = ", ".join(f"{name} {latency} us" for name, latency in self.states)
        states = f"cpu0's idle states (exit latency): {listed}" if listed else "no cpuidle states listed"
        return f"CPU wake-up latency {limit}; {states}"


def read_idle_states(device: Path = CPU_DMA_LATENCY, cpuidle: Path = CPU_IDLE) -> IdleStates:
    """The limit now (read from ``device``: opening it asks for nothing) and cpu0's idle states."""
    states = []
    folders = [path for path in cpuidle.glob("state*") if path.name[5:].isdigit()]
    for folder in sorted(folders, key=lambda path: int(path.name[5:])):
        try:
            name = (folder / "name").read_text().strip()
            states.append((name, int((folder / "latency").read_text())))
        except (OSError, ValueError):
            continue
    try:
        data = device.read_bytes()[:4]
    except OSError as error:
        return IdleStates(None, tuple(states), f"{device}: {error.strerror or error}")
    if len(data) != 4:
        return IdleStates(None, tuple(states), f"{device}: read {len(data)} bytes, not 4")
    return IdleStates(struct.unpack("=i", data)[0], tuple(states))


class IdleStateHold:
    """An open ``/dev/cpu_dma_latency`` asking for a limit; closing it (or :meth:`close`) lets the CPUs sleep.

    Build it with :func:`hold_idle_states`. Attributes: ``held`` (the request stands), ``statement`` (what
    it did, or what not holding costs and how to grant it).
    """

    def __init__(self, fd: int | None, statement: str) -> None:
        self._fd = fd
        self.statement = statement

    @property
    def held(self) -> bool:
        """True while the request stands."""
        return self._fd is not None

    def close(self) -> None:
        """Withdraws the request (idempotent)."""
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)

    def __enter__(self) -> IdleStateHold:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()


def hold_idle_states(
    limit_us: int = 0, device: Path = CPU_DMA_LATENCY, opener: Opener = os.open
) -> IdleStateHold:
    """Asks the kernel to keep every CPU's wake-up latency at most ``limit_us`` (us) while the hold is open.

    Never raises for a device it cannot open or write: the hold is then not held and its statement says
    what that costs and how to grant it.

    Raises:
        ValueError: ``limit_us`` not an int in [0, 2**31 - 1].
    """
    if isinstance(limit_us, bool) or not isinstance(limit_us, int) or not 0 <= limit_us < 2**31:
        raise ValueError(f"limit_us must be an int in [0, 2**31 - 1], got {limit_us!r}")
    try:
        fd = opener(str(device), os.O_WRONLY | os.O_CLOEXEC)
    except OSError as error:
        return IdleStateHold(None, _refusal(device, error))
    try:
        written = os.write(fd, struct.pack("=i", limit_us))
        if written != 4:
            raise OSError(errno.EIO, f"wrote {written} of 4 bytes")
    except OSError as error:
        os.close(fd)
        return IdleStateHold(None, _refusal(device, error))
    return IdleStateHold(
        fd,
        f"idle states: holding {device} at {limit_us} us for this run (machine-wide: no CPU sleeps in an "
        "idle state slower to leave; released at exit)",
    )


def _refusal(device: Path, error: OSError) -> str:
    """What not holding the limit costs, and how to grant it."""
    reasons = {
        errno.ENOENT: "absent (a kernel without PM QoS, or a container without the device)",
        errno.EACCES: "permission denied (root only by default)",
        errno.EPERM: "not permitted (root only by default)",
        errno.EROFS: "read-only (a container's /dev)",
    }
    reason = reasons.get(error.errno or 0, error.strerror or str(error))
    return (
        f"idle states: cannot hold {device} at 0: {reason}; the CPUs may sleep in deep idle states between "
        "board ticks and each wake-up then delays the loop (an idle PC refused at preflight where the same "
        f"PC with the device held passed: docs/LAUNCH.md, 'Idle states'); to grant it, {GRANT}"
    )
