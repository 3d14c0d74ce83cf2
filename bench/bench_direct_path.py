"""The direct loop's per-frame host work, in process: feedback frame in -> command frame out, no sockets.

Figures, not pass/fail (``make bench``). ``DirectBridgeNode._on_datagram`` is fed encoded feedback frames of
a board that follows case 1's reference; a transport stands in for the socket and notes when ``send`` is
called. Printed: receive -> send (what the board waits for, less the UDP hops) and the whole tick (the ROS
side after the send included), p50 / p99 / max over the frames, with and without a subscriber on every topic.
Runs in a private network namespace (as bench_hil.py).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FRAMES = int(os.environ.get("SMM_BENCH_DIRECT_FRAMES", "20000"))
COUNTS = 1 << 20


def run(observed: bool) -> dict[str, float]:
    """Per-frame times (us) of the direct loop's host; ``observed``: a subscriber on every topic."""
    import rclpy
    from rclpy.context import Context
    from smm_direct_loop.host import DirectBridgeNode, DirectControllerNode
    from smm_hw_bridge.core import BridgeCore
    from smm_hw_bridge.protocol import FeedbackFrame, decode_command, encode
    from smm_hw_bridge.transport import Transport
    from std_msgs.msg import Float64MultiArray

    from smm_msgs_py import topics

    sent_at: list[int] = []
    sent: list[bytes] = []

    class Noting(Transport):
        def send(self, frame: bytes) -> None:
            sent_at.append(time.perf_counter_ns())
            sent.append(frame)

        def receive(self, timeout_s: float = 0.0) -> bytes | None:
            return None

        def fileno(self) -> int:
            return -1

        def close(self) -> None:
            pass

    context = Context()
    rclpy.init(context=context)
    controller = DirectControllerNode(
        context=context,
        parameter_overrides={"chain": "internal", "reference_source": "internal", "reference.kind": "sine"},
    )
    bridge = DirectBridgeNode(controller, context=context, parameter_overrides={"bridge.lockstep": False})
    peer = rclpy.create_node("bench_peer", context=context)
    if observed:
        from sensor_msgs.msg import JointState

        peer.create_subscription(JointState, topics.JOINT_STATES, lambda _m: None, 10)
        arrays = (topics.TORQUE_COMMAND, topics.REFERENCE, topics.CONTROLLER_INTERNALS, "hw_bridge_internals")
        for name in arrays:
            peer.create_subscription(Float64MultiArray, name, lambda _m: None, 10)
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and controller._internals_publisher.get_subscription_count() == 0:
            time.sleep(0.05)
    host_session = 7
    core = BridgeCore(bridge._bridge.config, host_session=host_session)
    bridge._core, bridge._transport = core, Noting()

    def frame(tick: int, codes: tuple[int, int], applied_seq: int) -> bytes:
        angle = math.sin(math.pi * tick * 1e-3) * 0.5
        count = round(angle / (2 * math.pi) * COUNTS) % (1 << 32)
        return encode(
            FeedbackFrame(
                session=11,
                seq=tick + 1,
                tick=tick,
                host_session=host_session,
                counts=(count, count),
                adc=(1600, 0, 0, 0),
                status=0,
                faults=0,
                applied_seq=applied_seq,
                applied_age=0 if applied_seq else 0xFFFF,
                output_codes=codes,
                late_commands=0,
                crc_errors=0,
                dropped_frames=0,
            )
        )

    core.on_datagram(frame(0, (0, 0), 0), time.monotonic_ns())
    core.arm()
    send_us: list[float] = []
    tick_us: list[float] = []
    codes, applied = (0, 0), 0
    for tick in range(1, FRAMES + 1):
        data = frame(tick, codes, applied)
        count = len(sent_at)
        started = time.perf_counter_ns()
        bridge._on_datagram(data)
        ended = time.perf_counter_ns()
        if len(sent_at) > count:
            command = decode_command(sent[-1])
            codes, applied = command.codes, command.seq
            send_us.append((sent_at[count] - started) / 1e3)
        tick_us.append((ended - started) / 1e3)
    answered = len(send_us)
    peer.destroy_node()  # type: ignore[no-untyped-call]
    bridge._transport = None
    bridge.destroy_node()
    controller.destroy_node()  # type: ignore[no-untyped-call]
    rclpy.shutdown(context=context)
    steady_send = np.asarray(send_us[1000:])
    steady_tick = np.asarray(tick_us[1000:])
    return {
        "answered": answered,
        "send_p50": float(np.percentile(steady_send, 50)),
        "send_p99": float(np.percentile(steady_send, 99)),
        "send_max": float(steady_send.max()),
        "tick_p50": float(np.percentile(steady_tick, 50)),
        "tick_p99": float(np.percentile(steady_tick, 99)),
    }


def main(argv: list[str]) -> int:
    if "--inner" not in argv:
        sys.path.insert(0, str(HERE))
        from bench_graph import reexec_in_private_netns

        return reexec_in_private_netns(argv, __file__, domain_base=190, domains=10)
    for observed in (False, True):
        figures = run(observed)
        listeners = "every topic subscribed" if observed else "no subscriber"
        print(
            f"direct loop host, in process, {FRAMES} frames, {listeners}: "
            f"{figures['answered']:.0f} answered; receive -> send p50 {figures['send_p50']:.1f} us, "
            f"p99 {figures['send_p99']:.1f} us, max {figures['send_max']:.0f} us; whole tick p50 "
            f"{figures['tick_p50']:.1f} us, p99 {figures['tick_p99']:.1f} us"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
