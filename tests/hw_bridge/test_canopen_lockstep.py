"""CANopen in lockstep: a SYNC follows only an answer to the latest feedback (the frame board's rule).

A second answer to one feedback: test_canopen_device.py.
"""

from __future__ import annotations

from hw_bridge import test_canopen_device as emulated
from hw_bridge.test_canopen_device import TIMEOUT, _feedback, _open, _run
from smm_bench_emulator.canopen_bench import CanBench
from smm_hw_bridge.protocol import CommandFlag, FeedbackFrame
from udp_bench import answer

ENABLE = int(CommandFlag.ENABLE)
bench = emulated.bench  # the emulated bench on a fresh virtual channel (fixtures)
channel = emulated.channel


def test_a_late_answer_to_a_feedback_given_again_steps_nothing_and_the_latest_answer_steps(
    bench: CanBench, channel: str
) -> None:
    device = _open(channel)
    try:
        armed = _run(device, 5, (2000, 2000), ENABLE)
        again = device.read(TIMEOUT)  # no answer for 50 ms: the same feedback again (the controller slow)
        assert isinstance(again, FeedbackFrame) and again.seq == armed.seq
        device.write(answer(armed, 10, (2000, 2000), ENABLE))  # the answer to it
        latest = _feedback(device)
        assert latest.seq == armed.seq + 1
        device.write(answer(again, 11, (-4000, -4000), ENABLE))  # the answer to its copy, late
        device.write(answer(latest, 12, (3000, 3000), ENABLE))  # the answer to the latest
        after = _feedback(device)
        assert after.seq == latest.seq + 1 and bench.syncs == after.seq  # one step
        assert after.output_codes == (3000, 3000)  # the latest answer's setpoints, not the late one's
        assert device.dropped == {"stale_answer": 1}
    finally:
        device.close()
