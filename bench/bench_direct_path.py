"""The direct loop's per-frame host work: feedback frame received -> command frame sent, through public API.

Figures, not pass/fail (``make bench``). The emulator's board (``smm_bench_emulator.board.BoardCore``) sits
behind an in-memory link that the bridge opens at configure (a new feedback frame each time the reader asks:
no sockets, no clock to wait for). ``controller_node`` and ``hw_bridge_node``, composed as the direct loop
composes them (``smm_direct_loop.host.compose``), are configured and activated through their lifecycle; the
bridge loop's ``statistics`` (receive -> send of each answered frame,
the figure the direct loop reports on /diagnostics) gives p50 / p99 / max, with and without a subscriber on
every topic, printed beside the time of a fixed pure-Python loop so that machines compare. A run the bridge
ends (a fault) prints what it had. ``--profile``: a cProfile of the controller's part of a tick instead.
Runs in a private network namespace (as bench_hil.py).
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import threading
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
FRAMES = int(os.environ.get("SMM_BENCH_DIRECT_FRAMES", "5000"))
WARM_UP = 1000
"""Frames left out of the figures (imports, first allocations, the arming handshake)."""


def reference_loop_s() -> float:
    """Seconds of the fixed pure-Python reference loop ``s = 0; for i in range(3_000_000): s += i * i``."""
    started = time.perf_counter()
    s = 0
    for i in range(3_000_000):
        s += i * i
    return time.perf_counter() - started


def run(observed: bool) -> dict[str, Any]:
    """Receive -> send (us) of the direct loop's host; ``observed``: a subscriber on every topic."""
    import rclpy
    import smm_hw_bridge.bridge_node
    from rclpy.context import Context
    from sensor_msgs.msg import JointState
    from smm_bench_emulator.board import BoardConfig, BoardCore
    from smm_direct_loop.host import compose
    from smm_hw_bridge.canopen_config import CanopenConfig
    from smm_hw_bridge.core import BridgeConfig
    from smm_hw_bridge.device import Device, Link
    from smm_hw_bridge.frame_device import FrameDevice
    from smm_hw_bridge.transport import Transport
    from std_msgs.msg import Float64MultiArray

    from smm_msgs_py import topics
    from smm_node_runtime import make_executor, spin_until_shutdown

    class Board(Transport):
        """The emulator's board behind an in-memory link: a new feedback frame each time one is read.

        The board ticks when the host asks for the next frame (its lockstep tick once the last feedback is
        answered, else its own tick), so the host never waits for a clock and no other process runs.
        """

        def __init__(self) -> None:
            super().__init__()
            self.board = BoardCore(BoardConfig())
            self.first: bytes | None = self.board.start()

        def send(self, frame: bytes) -> None:
            self.board.receive(frame)

        def receive(self, timeout_s: float = 0.0) -> bytes | None:
            first, self.first = self.first, None
            if first is not None:
                return first
            return self.board.tick_lockstep() if self.board.answered else self.board.tick_realtime()

        def fileno(self) -> int:
            return -1

        def close(self) -> None:
            pass

    def open_board(link: Link, canopen: CanopenConfig, bridge: BridgeConfig) -> Device:
        device = FrameDevice("udp", Board)
        device.open()
        return device

    # The one seam: the device the bridge opens at configure (a public function of its module, no member).
    smm_hw_bridge.bridge_node.open_device = open_board  # type: ignore[attr-defined]
    context = Context()
    rclpy.init(context=context)
    # A busy machine's pauses must not take the in-memory link down (the board waits for the host anyway).
    controller, bridge = compose(
        context,
        {"chain": "internal", "reference_source": "internal", "reference.kind": "sine"},
        {"loop.spin_us": 0, "bridge.link_timeout_ns": 30_000_000_000},
    )
    peer = rclpy.create_node("bench_peer", context=context)
    if observed:
        peer.create_subscription(JointState, topics.JOINT_STATES, lambda _m: None, 10)
        arrays = (topics.TORQUE_COMMAND, topics.REFERENCE, topics.CONTROLLER_INTERNALS, "hw_bridge_internals")
        for name in arrays:
            peer.create_subscription(Float64MultiArray, name, lambda _m: None, 10)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and controller.count_subscribers(topics.CONTROLLER_INTERNALS) == 0:
            time.sleep(0.05)
    executor = make_executor(context)  # the direct_loop process's executor
    for node in (controller, bridge, peer):
        executor.add_node(node)
    stop = threading.Event()
    spinner = threading.Thread(target=spin_until_shutdown, args=(executor, context, stop.is_set), daemon=True)
    spinner.start()
    try:
        bridge.trigger_configure()  # type: ignore[no-untyped-call]
        bridge.trigger_activate()  # type: ignore[no-untyped-call]
        statistics = bridge.loop.statistics
        deadline = time.monotonic() + float(os.environ.get("SMM_BENCH_DIRECT_WAIT", "60"))
        while statistics.execution_us.count < WARM_UP and time.monotonic() < deadline:
            time.sleep(0.01)
        if statistics.execution_us.count < WARM_UP:
            raise RuntimeError(
                f"the loop did not start: {statistics.execution_us.count} frames answered, bridge "
                f"{bridge.lifecycle_state} ({None if bridge.core is None else bridge.core.state}), "
                f"{bridge.counters}, controller {controller.counters}"
            )
        statistics.reset()
        started = time.monotonic()
        deadline = started + 600.0
        while (
            statistics.execution_us.count < FRAMES
            and time.monotonic() < deadline
            and bridge.lifecycle_state == "active"
        ):
            time.sleep(0.1)  # this thread's wake-ups take the GIL from the reader: few of them
        seconds = time.monotonic() - started
        figures = {
            "answered": float(statistics.execution_us.count),
            "rate_hz": statistics.execution_us.count / seconds,
            "send_p50": statistics.execution_percentile_us(50),
            "send_p99": statistics.execution_percentile_us(99),
            "send_max": statistics.execution_us.maximum,
            "publish_mean": bridge.publish_us.mean,
            "state": bridge.lifecycle_state,
        }
    finally:
        if bridge.lifecycle_state == "active":
            bridge.trigger_deactivate()  # type: ignore[no-untyped-call]
        stop.set()  # the spinner ends between two callbacks, then the executor is shut down
        spinner.join(10.0)
        executor.shutdown()
        with contextlib.redirect_stdout(io.StringIO()):  # its closing line judges an in-memory board's
            bridge.destroy_node()  # lateness, which ticks when asked: meaningless here
        controller.destroy_node()  # type: ignore[no-untyped-call]
        peer.destroy_node()  # type: ignore[no-untyped-call]
        rclpy.shutdown(context=context)
    return figures


def profile(frames: int) -> None:
    """cProfile of the controller's part of a tick (the answerer's ``answer``, ``published``, ``prepare``)."""
    import cProfile
    import math
    import pstats

    import numpy as np
    import rclpy
    from rclpy.context import Context
    from smm_controller.chain import make_chain
    from smm_controller.controller_node import ControllerNode
    from smm_direct_loop.host import HostedController
    from smm_hw_bridge.loop import ChangeBuffer

    from smm_dynamics import SMMParameters

    context = Context()
    rclpy.init(context=context)
    controller = ControllerNode(
        changes=ChangeBuffer(),
        context=context,
        parameter_overrides={"chain": "internal", "reference_source": "internal", "reference.kind": "sine"},
    )
    hosted = HostedController(controller)
    measurements = [
        (k * 1_000_000, (0.5 * math.sin(math.pi * k * 1e-3), 0.5 * math.sin(math.pi * k * 1e-3)), (0.0, 0.0))
        for k in range(1, frames + 1)
    ]
    half = frames // 2
    command_ns: list[int] = []
    for stamp_ns, position, effort in measurements[:half]:  # unprofiled: the real cost of each part
        started = time.perf_counter_ns()
        hosted.answer(stamp_ns, position, effort)
        command_ns.append(time.perf_counter_ns() - started)
        hosted.published()
        hosted.prepare()  # after the send, as the direct loop does
    chain = make_chain("fpdeso", SMMParameters())
    chain_ns: list[int] = []
    rows = ((0.1, 0.1), (0.0, 0.0), (0.0, 0.0))
    for _, position, effort in measurements[:half]:
        started = time.perf_counter_ns()
        chain.step_floats(position, effort, rows, 1e-3)
        chain_ns.append(time.perf_counter_ns() - started)
    print(
        f"controller part before the send (answer), p50 {np.percentile(command_ns, 50) / 1e3:.1f} us, "
        f"p99 {np.percentile(command_ns, 99) / 1e3:.1f} us; of which the chain's own step (ControlChain."
        f"step_floats alone) p50 {np.percentile(chain_ns, 50) / 1e3:.1f} us, "
        f"p99 {np.percentile(chain_ns, 99) / 1e3:.1f} us"
    )
    profiler = cProfile.Profile()
    profiler.enable()
    for stamp_ns, position, effort in measurements[half:]:
        hosted.answer(stamp_ns, position, effort)
        hosted.published()
        hosted.prepare()
    profiler.disable()
    controller.destroy_node()  # type: ignore[no-untyped-call]
    rclpy.shutdown(context=context)
    print(f"cProfile of {frames - half} ticks' controller part (answer, published, prepare):")
    pstats.Stats(profiler).sort_stats("tottime").print_stats(18)


def main(argv: list[str]) -> int:
    """Re-executes in a private network namespace, then prints the figures."""
    if "--inner" not in argv:
        sys.path.insert(0, str(HERE))
        from bench_graph import reexec_in_private_netns

        return reexec_in_private_netns(argv, __file__, domain_base=190, domains=10)
    if "--profile" in argv:
        profile(FRAMES)
        return 0
    reference = reference_loop_s()
    print(f"reference loop (s = 0; for i in range(3_000_000): s += i * i): {reference:.3f} s", flush=True)
    for observed in (False, True):
        figures = run(observed)
        listeners = "every topic subscribed" if observed else "no subscriber"
        print(
            f"direct loop host, in process, {figures['answered']:.0f} frames "
            f"({figures['rate_hz']:.0f} Hz), {listeners}: receive -> send p50 {figures['send_p50']:.1f} us, "
            f"p99 {figures['send_p99']:.1f} us, max {figures['send_max']:.0f} us; ROS side after the send "
            f"mean {figures['publish_mean']:.1f} us; reference loop {reference:.3f} s"
            + ("" if figures["state"] == "active" else f"; the bridge ended the run ({figures['state']})"),
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
