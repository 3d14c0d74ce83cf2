"""SCHED_FIFO for the processes of the control loop (``--rt-priority``; docs/NODES.md, "Real time")."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
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


def fifo_preexec(priority: int) -> Callable[[], None]:
    """A ``Popen(preexec_fn=...)`` that puts the child under SCHED_FIFO before it starts any thread.

    A negative ``priority`` is a nice value under normal scheduling instead (left as it is where refused).
    """

    def apply() -> None:
        if priority < 0:
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, 0, priority)
            with contextlib.suppress(OSError):  # a session is an autogroup: a nice counts only inside it
                Path("/proc/self/autogroup").write_text(str(priority))
            return
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))

    return apply
