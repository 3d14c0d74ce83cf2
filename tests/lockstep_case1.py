"""Case 1 (5 s) closed in one process: bridge core + board core in lockstep with the FPDESO chain.

At ``bridge.control_divider`` N > 1 the chain steps every N board ticks with dt = N ms and the settings of
that rate's file (smm_bringup.graph.control_rate_configs); the board holds the command in between, as the
emulator in lockstep.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from smm_bench_emulator.board import BoardConfig, BoardCore
from smm_bringup.graph import control_rate_configs
from smm_controller.chain import build_chain
from smm_controller.fpdeso import FPDESOController
from smm_controller.reference import SineReference
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeState
from smm_hw_bridge.protocol import encode
from smm_node_runtime.parameter_files import load_parameter_file
from smm_schema.fields import config_from_parameters

from smm_dynamics import SMMParameters

MS = 1_000_000
SETTLED = 1000
"""Ticks of case 1's start (the valves saturate: 34 N m demanded of 10) left out of the RMS compared."""


def bridge_config(path: Path | None) -> BridgeConfig:
    base = BridgeConfig(lockstep=True)
    if path is None:
        return base
    parameters = load_parameter_file(path, "/smm/hw_bridge_node")
    return config_from_parameters(BridgeConfig, base, parameters, prefix="bridge")


def case1(board_config: BoardConfig, bridge_config: BridgeConfig) -> tuple[np.ndarray, float]:
    """Tracking errors of 5 s of case 1 at every board tick (rad, shape (5000, 2)) and the largest |q| (rad).

    Raises:
        AssertionError: The bridge left ARMED or called a safety stop (its reason).
    """
    board, bridge = BoardCore(board_config), BridgeCore(bridge_config, host_session=0x3333)
    now = 0

    def deliver() -> None:
        nonlocal now
        now += MS
        bridge.on_datagram(encode(board.last_feedback), now)  # type: ignore[arg-type]

    def send() -> None:
        frame = bridge.next_frame(now)
        assert frame is not None
        board.receive(encode(frame))

    board.start()
    deliver()
    send()
    deliver()
    bridge.arm()
    send()
    deliver()
    divider = bridge_config.control_divider
    dt = divider * 1e-3
    td, law = control_rate_configs(1000 // divider)
    chain = build_chain("fpdeso", SMMParameters(), law=FPDESOController(law, SMMParameters()), td=td)
    reference = SineReference()
    errors, peak = [], 0.0
    for step in range(5000):
        if bridge.control_tick:  # board ticks that are multiples of N, as the bridge's loop answers
            torque = chain.step(bridge.position, bridge.applied_torque, reference.rows(step * 1e-3), dt)
            assert bridge.on_command(torque, bridge.stamp_ns, now) is None
            send()
            assert board.answered_enabled and bridge.state == BridgeState.ARMED
        board.tick_lockstep()
        deliver()
        assert bridge.limit_stop() is None, bridge.limit_stop()
        t = (step + 1) * 1e-3
        alpha, beta = board.plant.state_floats[:2]
        errors.append((alpha - math.sin(math.pi * t), beta - 0.785 * math.sin(math.pi * t)))
        peak = max(peak, abs(alpha), abs(beta))
    return np.array(errors), peak


def rms(errors: np.ndarray) -> np.ndarray:
    return np.asarray(np.sqrt(np.mean(errors**2, axis=0)), dtype=np.float64)
