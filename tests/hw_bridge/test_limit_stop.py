"""The bridge's safety stop: a joint past its soft limit by the margin, or running away, is a host fault.

The loop on the emulator's board (in memory) with the FPDESO chain (or PID) answering: a bench whose truths
the bridge's defaults get wrong (issue 44's reversed bench, docs/BENCH.md; a reversed valve alone; a
down-counting encoder alone) ends with safe output, a reason an engineer acts on, and no joint at its 1.3 rad
stop; the default bench runs the paper's cases without a stop.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import pytest
from memory_board import MemoryBoard
from smm_bench_emulator.bench_file import default_bench, load_bench_file
from smm_bench_emulator.board import BoardConfig, BoardCore
from smm_controller.chain import build_chain
from smm_controller.reference import SineReference
from smm_controller.td import TrackingDifferentiatorConfig
from smm_hw_bridge.bridge_health import BridgeCounters
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeState
from smm_hw_bridge.frame_device import FrameDevice
from smm_hw_bridge.link import AdmissionConfig
from smm_hw_bridge.loop import BridgeLoop, first_feedback
from smm_hw_bridge.protocol import decode_command
from smm_hw_bridge.run_verdict import RunTally
from smm_hw_bridge.safety_stop import SafetyStopConfig

from smm_dynamics import SMMParameters

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "src" / "smm_bench_emulator" / "config" / "bench_reversed.yaml"
STOP = 1.3
"""The emulated plant's mechanical stops (rad)."""


class Fpdeso:
    """A chain (nominal model; FPDESO unless told) tracking case 1's sine as the loop's answerer."""

    def __init__(self, law: str = "fpdeso", divider: int = 1) -> None:
        td = TrackingDifferentiatorConfig(filter_factor=(0.01, 0.01)) if divider > 1 else None
        self.chain, self.reference = build_chain(law, SMMParameters(), td=td), SineReference()
        self.steps = 0
        self.dt = divider * 1e-3

    def answer(
        self, stamp_ns: int, position: tuple[float, float], effort: tuple[float, float]
    ) -> tuple[float, float]:
        rows = self.reference.rows(self.steps * self.dt)
        torque = self.chain.step(np.array(position), np.array(effort), rows, self.dt)
        self.steps += 1
        return float(torque[0]), float(torque[1])

    def published(self) -> None:
        pass

    def prepare(self) -> None:
        pass

    def forget(self) -> None:
        pass


def run(
    bench: BoardConfig, config: BridgeConfig, seconds: float = 4.0, answerer: Fpdeso | None = None
) -> tuple[BridgeLoop, MemoryBoard, float]:
    """Arms the bridge's loop on ``bench`` and ticks it ``seconds``: the loop, the board, the largest |q|."""
    board = MemoryBoard(bench)
    device = FrameDevice("memory", lambda: board)
    device.open()
    core = BridgeCore(config, host_session=7)
    assert first_feedback(device, core, 1.0, "memory") is None
    loop = BridgeLoop(BridgeCounters(), answerer or Fpdeso())
    loop.attach(core, device, RunTally(config.period_ns))
    core.arm()
    peak = 0.0
    for _ in range(round(seconds * 1000)):
        board.tick()
        reading = loop.read()
        assert reading is not None
        loop.on_feedback(reading, time.monotonic_ns())
        peak = max(peak, *(abs(q) for q in board.board.plant.state_floats[:2]))
    return loop, board, peak


SLACK = BridgeConfig(
    admission=AdmissionConfig(stale_ns=60_000_000_000),
    host_watchdog_ns=10_000_000_000,
    link_timeout_ns=60_000_000_000,
)
"""Times are slack: no test depends on speed."""


CASE2 = dataclasses.replace(
    default_bench(),
    plant=dataclasses.replace(
        default_bench().plant, noise_std=(1e-3, 1e-3), disturbance="eq46", inertia_scale=1.1
    ),
)
"""The default bench with case 2's plant: 1 mrad noise, the eq. 46 disturbance, inertias 1.1x."""


@pytest.mark.parametrize(
    ("bench", "law", "divider", "peak_range"),
    [
        (default_bench(), "fpdeso", 1, (0.9, 1.1)),
        (CASE2, "fpdeso", 1, (0.9, 1.1)),
        # the hardware graph's run: PID at 250 Hz swings beta onto its stop (a run that controls, badly)
        (default_bench(), "pid", 4, (0.9, STOP + 1e-9)),
        (CASE2, "pid", 4, (0.9, STOP + 1e-9)),
    ],
    ids=["case1", "case2", "case1-pid-250Hz", "case2-pid-250Hz"],
)
def test_the_default_bench_tracks_without_a_stop(
    bench: BoardConfig, law: str, divider: int, peak_range: tuple[float, float]
) -> None:
    config = dataclasses.replace(SLACK, control_divider=divider)
    loop, _, peak = run(bench, config, answerer=Fpdeso(law, divider))
    assert loop.host_fault == "" and loop.core is not None and loop.core.state == BridgeState.ARMED
    assert peak_range[0] < peak < peak_range[1]


@pytest.mark.parametrize(
    ("truths", "joint"),
    [({"valve_polarity": (-1, -1)}, "alpha"), ({"direction": (-1, -1)}, "alpha")],
    ids=["reversed valve", "down-counting encoder"],
)
@pytest.mark.parametrize(("law", "divider"), [("fpdeso", 1), ("pid", 4)], ids=["fpdeso", "pid-250Hz"])
def test_with_the_defaults_a_joint_running_away_is_stopped_short_of_its_stop(
    truths: dict[str, tuple[int, int]], joint: str, law: str, divider: int
) -> None:
    """The check of a joint accelerating against its torque: the soft limit's margin alone would not."""
    config = dataclasses.replace(SLACK, control_divider=divider)
    loop, board, peak = run(
        dataclasses.replace(default_bench(), **truths), config, answerer=Fpdeso(law, divider)
    )
    assert loop.host_fault.startswith(f"safety stop: joint {joint} accelerates at "), loop.host_fault
    assert "check bridge.valve.polarity and bridge.encoder.direction" in loop.host_fault
    assert loop.safety_stop == loop.host_fault
    assert not decode_command(board.sent[-1]).enabled
    assert peak < 0.3, peak  # stopped early, held by the trapped oil
    without = dataclasses.replace(config, limit_stop=SafetyStopConfig(runaway_window=0.0))
    loop, _, peak = run(
        dataclasses.replace(default_bench(), **truths), without, answerer=Fpdeso(law, divider)
    )
    assert peak >= STOP - 1e-6  # the margin alone: the joint reaches its stop


def test_the_reversed_bench_with_the_bridge_defaults_stops_at_once_reading_the_encoder_zero() -> None:
    loop, board, peak = run(load_bench_file(BENCH), SLACK)
    assert "safety stop: joint alpha reads 5.992 rad (" in loop.host_fault, loop.host_fault
    assert "bridge.encoder.direction / zero_offset" in loop.host_fault
    assert loop.fault_signalled and loop.fault() == f"host fault ({loop.host_fault})"
    assert loop.safety_stop == loop.host_fault  # kept for the run's verdict
    assert not any(decode_command(frame).enabled for frame in board.sent)  # the valves never opened
    assert peak < 0.01  # held by the trapped oil where it started


@pytest.mark.parametrize(("margin", "lead"), [(1.0, 0.0), (0.05, 0.0), (0.05, 0.01)])
def test_a_reversed_valve_runs_away_and_a_stop_with_a_lead_holds_it_short_of_the_stop(
    margin: float, lead: float
) -> None:
    """The soft limit's cut passes the torque that drives back, which this valve turns outwards.

    Margin 1 rad: no safety stop, the joint reaches its stop. 0.05 rad without a lead stops it at 1.25 rad,
    too late at full speed (it still reaches the stop); 10 ms of lead holds it short of the stop.
    """
    bench = dataclasses.replace(default_bench(), valve_polarity=(-1, -1))
    limit_stop = SafetyStopConfig(margin=margin, lead=lead, runaway_window=0.0)  # the margin alone
    config = dataclasses.replace(SLACK, limit_stop=limit_stop)
    loop, board, peak = run(bench, config)
    if margin == 1.0:
        assert loop.host_fault == "" and peak >= STOP - 1e-6
        return
    assert "safety stop: joint" in loop.host_fault and "past its soft limit 1.2 rad" in loop.host_fault
    assert not decode_command(board.sent[-1]).enabled
    if lead == 0.0:
        assert peak >= STOP - 1e-6, peak
    else:
        assert 1.2 < peak < STOP - 0.005, peak  # past the soft limit, held short of the stop


def test_in_lockstep_an_activation_judges_the_reading_the_board_holds() -> None:
    """The lockstep board re-sends its feedback (a duplicate, not admitted) until a command answers it."""
    board = BoardCore(load_bench_file(BENCH))
    core = BridgeCore(dataclasses.replace(SLACK, lockstep=True), host_session=9)
    core.on_datagram(board.start(), 1)
    assert core.limit_stop() is None  # not armed
    core.arm()
    assert str(core.limit_stop()).startswith("safety stop: joint alpha reads 5.992 rad (")
