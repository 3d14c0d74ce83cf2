"""SCHED_FIFO for the processes of the control loop (``--rt-priority``; docs/NODES.md, "Real time")."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Final

DEFAULT_HARDWARE_PRIORITY: Final[int] = 50
"""Priority of the loop processes with ``plant hardware`` (ros2_control's controller manager uses 50)."""
BOARD_PRIORITY_OFFSET: Final[int] = 20
"""The bench emulator stands for the hard real-time board: it runs this much above the loop (at most 99)."""
BRIDGE_PRIORITY_OFFSET: Final[int] = 5
"""``hw_bridge_node`` (the I/O, as ros2_control's read/write thread) runs this much above the controller, so a
controller busy at start-up cannot starve the bridge's reader into a link loss (seen: 326 frames missed)."""
RECORDER_PRIORITY_OFFSET: Final[int] = 10
"""The recorder runs this much below the loop (at least 1): above the host's ordinary processes, which
otherwise starve it of the CPU the loop leaves (measured: half of a 1 kHz run lost at normal priority)."""
MAX_PRIORITY: Final[int] = 99
OBSERVER_SPARE_CPUS: Final[int] = 2
"""An observer (the recorder) runs SCHED_FIFO only with this many CPUs beyond one per loop process: one for
it, one for everything else (docs/SOAK.md, "Real time beside the loop")."""
OBSERVER_NICE: Final[int] = -10
"""Otherwise it runs at normal policy with this nice value: ahead of the host's ordinary processes, outside
the kernel's real-time budget."""


def observer_fifo_allowed(loop_processes: int, cpus: int) -> bool:
    """Whether an observer may run SCHED_FIFO beside ``loop_processes`` real-time ones on ``cpus`` CPUs."""
    return cpus >= loop_processes + OBSERVER_SPARE_CPUS


def fifo_allowed(priority: int) -> bool:
    """Whether this process may use SCHED_FIFO at ``priority`` (CAP_SYS_NICE or RLIMIT_RTPRIO).

    Tried on this process and undone at once.
    """
    policy, parameters = os.sched_getscheduler(0), os.sched_getparam(0)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError:
        return False
    os.sched_setscheduler(0, policy, parameters)
    return True


@dataclass(frozen=True)
class Scheduling:
    """How a child process runs: SCHED_FIFO at ``priority``, or normal policy at ``nice``.

    Make it with :func:`fifo` or :func:`nice`; ``Scheduling()`` is normal policy as inherited.

    Attributes:
        priority: SCHED_FIFO priority in [1, :data:`MAX_PRIORITY`], 0 for normal policy.
        nice: Nice value under normal policy, in [-20, 19]; only with ``priority`` 0.
    """

    priority: int = 0
    nice: int = 0

    def __post_init__(self) -> None:
        for name, low, high in (("priority", 0, MAX_PRIORITY), ("nice", -20, 19)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise ValueError(f"{name} must be an int in [{low}, {high}], got {value!r}")
        if self.priority and self.nice:
            raise ValueError(f"SCHED_FIFO {self.priority} has no nice value, got nice {self.nice}")

    def describe(self) -> str:
        """``", SCHED_FIFO <p>"``, ``", nice <n>"`` or "" (the tail of the launcher's ``started`` line)."""
        if self.priority:
            return f", SCHED_FIFO {self.priority}"
        return f", nice {self.nice}" if self.nice else ""

    def preexec(self) -> Callable[[], None] | None:
        """A ``Popen(preexec_fn=...)`` that sets it before the child starts any thread; None: nothing to set.

        A nice value is set for the process and its session's autogroup, each left as it is where refused.
        """
        priority, value = self.priority, self.nice
        if not priority and not value:
            return None

        def apply() -> None:
            if priority:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
                return
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, 0, value)
            with contextlib.suppress(OSError):  # a session is an autogroup: a nice counts only inside it
                Path("/proc/self/autogroup").write_text(str(value))

        return apply


def fifo(priority: int) -> Scheduling:
    """SCHED_FIFO at ``priority`` (1-99; 0: normal policy)."""
    return Scheduling(priority=priority)


def nice(value: int) -> Scheduling:
    """Normal policy with the nice value ``value`` (-20..19)."""
    return Scheduling(nice=value)
