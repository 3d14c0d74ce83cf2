"""A closed loop over the bench for identify and verify: the bridge's core, a control chain and a reference.

The core maps the chain's torque to D/A codes with the commissioned ``bridge.*`` parameters and runs its
arming, watchdog and soft limits; one feedback, one answer (lockstep on the emulated bench: the answer ticks
it). docs/COMMISSIONING.md, "identify".
"""

from __future__ import annotations

import math
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from smm_controller.chain import ControlChain
from smm_controller.reference import Reference
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeState
from smm_hw_bridge.device import Feedback

from smm_commissioning.errors import MotionStopError
from smm_commissioning.host import BenchHost
from smm_commissioning.probe import JOINTS

__all__ = ["LoopRecord", "run_loop"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class LoopRecord:
    """One closed-loop run, one row per answered feedback (n rows).

    Attributes:
        t_ns: Time since the first answered feedback (ns), int64, shape (n,).
        reference: q_d, q_d', q_d'' at each row, shape (n, 3, 2) (rad, rad/s, rad/s^2).
        position: Measured joint angles (rad), shape (n, 2).
        effort: Torque the bridge's valve model says the valves gave over the tick before (N m), (n, 2).
        measured: Torque of the load pressure over the tick before (N m), shape (n, 2).
        command: The chain's torque answering each row (N m), shape (n, 2).
        codes: D/A codes sent in the answer, shape (n, 2).
    """

    t_ns: NDArray[np.int64]
    reference: FloatArray
    position: FloatArray
    effort: FloatArray
    measured: FloatArray
    command: FloatArray
    codes: NDArray[np.int64]

    @property
    def peak(self) -> tuple[float, float]:
        """Largest |q| each joint reached (rad)."""
        largest = np.abs(self.position).max(axis=0) if len(self.position) else np.zeros(2)
        return float(largest[0]), float(largest[1])

    def tracking_rms(self, after_s: float = 0.0) -> tuple[float, float]:
        """RMS of q - q_d per joint over the rows from ``after_s`` s on (rad)."""
        rows = self.t_ns >= round(after_s * 1e9)
        error = self.position[rows] - self.reference[rows, 0, :]
        rms = np.sqrt(np.mean(error**2, axis=0))
        return float(rms[0]), float(rms[1])


def run_loop(
    host: BenchHost,
    bridge: BridgeConfig,
    chain: ControlChain,
    reference: Reference,
    duration_s: float,
    *,
    max_error: float,
) -> LoopRecord:
    """Arms the bridge's core on the bench and closes the loop for ``duration_s`` (s), the output left live.

    The caller makes the bench safe.

    Raises:
        MotionStopError: A soft limit, a board fault or e-stop, a refused command, or a tracking error past
            ``max_error`` (rad): the loop does not follow, the commissioned parameters are wrong.
        LinkLostError: No feedback, or the board restarted.
        ValueError: ``bridge.control_divider`` is not 1 (commissioning answers every board tick).
    """
    if bridge.control_divider != 1:
        raise ValueError(
            "commissioning closes the loop at every board tick: bridge.control_divider must be 1"
        )
    core = BridgeCore(bridge, host_session=secrets.randbelow(0xFFFF_FFFE) + 1)
    period_ns = bridge.period_ns
    clock: Callable[[Feedback], int] = (
        (lambda frame: frame.tick * period_ns) if bridge.lockstep else (lambda _: time.monotonic_ns())
    )

    def admit() -> int:
        frame = host.feedback if host.feedback is not None else host.next()
        now = clock(frame)
        core.on_feedback(frame, now)
        return now

    def send(now: int) -> tuple[int, int]:
        frame = core.next_frame(now)
        codes = (0, 0)
        if frame is not None:
            host.device.write(frame)
            codes = frame.codes
        host.next()
        return codes

    send(admit())  # a disabled frame first: the board takes this host
    now = admit()
    core.arm()
    send(now)
    steps = math.ceil(duration_s * 1e9 / period_ns)
    dt = period_ns * 1e-9
    rows: list[tuple[float, ...]] = []
    for step in range(steps):
        now = admit()
        _check(core, step)
        t = step * dt
        wanted = reference.rows(t)
        position, effort = core.position_floats, core.applied_torque_floats
        measured = core.measured_torque
        for j in range(2):
            error = position[j] - wanted[0][j]
            if abs(error) > max_error:
                raise MotionStopError(
                    f"the loop stopped at {t:.3f} s: {JOINTS[j]} is {error:+.3f} rad off its reference "
                    f"(at most {max_error:g}): the commissioned valve or encoder parameters do not match the "
                    "bench; run jog again"
                )
        torque = chain.step_floats(position, effort, wanted, dt)
        refusal = core.on_command(torque, core.stamp_ns, now)
        if refusal is not None:
            raise MotionStopError(f"the bridge refused the command at {t:.3f} s ({refusal.value})")
        codes = send(now)
        rows.append(
            (
                float(step * period_ns),
                *wanted[0],
                *wanted[1],
                *wanted[2],
                *position,
                *effort,
                float(measured[0]),
                float(measured[1]),
                *torque,
                *codes,
            )
        )
    table = np.asarray(rows, dtype=np.float64).reshape(-1, 17)
    return LoopRecord(
        t_ns=table[:, 0].astype(np.int64),
        reference=table[:, 1:7].reshape(-1, 3, 2),
        position=table[:, 7:9],
        effort=table[:, 9:11],
        measured=table[:, 11:13],
        command=table[:, 13:15],
        codes=table[:, 15:17].astype(np.int64),
    )


def _check(core: BridgeCore, step: int) -> None:
    """Stops the loop on a safety stop of the core (soft limit), a board fault or an e-stop."""
    stop = core.limit_stop()
    if stop is not None:
        raise MotionStopError(f"the loop stopped at step {step}: {stop}")
    if core.state in (BridgeState.FAULT, BridgeState.ESTOP, BridgeState.SESSION_LOST):
        last = core.last_feedback
        faults = 0 if last is None else last.faults
        raise MotionStopError(
            f"the loop stopped at step {step}: the bridge is {core.state.value} (board faults "
            f"{faults:#06x}); run probe again once it is cleared"
        )
