"""Hand-built blocks of joined steps (runs.stream.StepBlock) for tests that need no bag."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from smm_analysis.runs.stream import StepBlock


def step_block(
    t_ns: np.ndarray,
    *,
    desired: np.ndarray | None = None,
    position: np.ndarray | None = None,
    torque: np.ndarray | None = None,
    latency_ns: Sequence[int] | None = None,
    first_step: int = 0,
) -> StepBlock:
    """A block at ``t_ns`` (n,): q_d, q and the command (n, 2) default to zeros, q_d' = q_d'' = 0."""
    n = t_ns.size
    reference = np.zeros((n, 3, 2))
    if desired is not None:
        reference[:, 0, :] = desired
    zeros = np.zeros((n, 2))
    return StepBlock(
        first_step=first_step,
        t_ns=np.asarray(t_ns, dtype=np.int64),
        reference=reference,
        position=zeros if position is None else np.asarray(position, dtype=np.float64),
        measured_position=zeros if position is None else np.asarray(position, dtype=np.float64),
        command_torque=zeros if torque is None else np.asarray(torque, dtype=np.float64),
        applied_torque=np.full((n, 2), np.nan),
        disturbance_estimate=np.full((n, 2), np.nan),
        internals={},
        latency_ns=np.zeros(n, dtype=np.int64) if latency_ns is None else np.asarray(latency_ns, np.int64),
    )
