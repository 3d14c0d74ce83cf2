"""The bridge's loop on an in-memory device (the emulator's board, no socket, no ROS): answer and write in
one call, the topics loop's command path, changes at the tick boundary, faults, the rehearsal, the table."""

from __future__ import annotations

import time
from typing import Any

import pytest
from memory_board import MemoryBoard
from smm_hw_bridge.bridge_health import BridgeCounters
from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeState
from smm_hw_bridge.device import DEVICES, Device, device_names, open_device
from smm_hw_bridge.frame_device import FrameDevice
from smm_hw_bridge.link import AdmissionConfig
from smm_hw_bridge.loop import REHEARSAL_STAMP_OFFSET_NS, BridgeLoop, ChangeBuffer, Tick, first_feedback
from smm_hw_bridge.preflight import RehearsalRecorder
from smm_hw_bridge.protocol import CommandFrame, Reason, decode_command
from smm_hw_bridge.run_verdict import RunTally
from smm_hw_bridge.transport import LinkConfig

TORQUE = (0.3, -0.2)


def memory_device(link: LinkConfig, canopen: CanopenConfig, bridge: BridgeConfig) -> Device:
    """The factory of the ``memory`` row a test adds to the device table."""
    board = MemoryBoard()
    return FrameDevice("memory", lambda: board)


class Chain:
    """An answerer: a fixed torque, or whatever ``result`` says; notes every call and what it saw."""

    def __init__(self) -> None:
        self.result: Any = TORQUE
        self.gain = 1.0
        self.calls: list[tuple[int, float]] = []
        self.published_count = 0
        self.forgotten = 0

    def answer(self, stamp_ns: int, position: tuple[float, float], effort: tuple[float, float]) -> Any:
        self.calls.append((stamp_ns, self.gain))
        if isinstance(self.result, Exception):
            raise self.result
        return self.result

    def published(self) -> None:
        self.published_count += 1

    def prepare(self) -> None:
        pass

    def forget(self) -> None:
        self.forgotten += 1


def attached(
    answerer: Any = None,
    changes: ChangeBuffer | None = None,
    watchdog_ns: int = 10_000_000_000,
    divider: int = 1,
) -> tuple[BridgeLoop, MemoryBoard]:
    """A loop on an in-memory board, configured; times are slack (no test depends on speed)."""
    board = MemoryBoard()
    device = FrameDevice("memory", lambda: board)
    device.open()
    slack = AdmissionConfig(stale_ns=60_000_000_000)
    config = BridgeConfig(
        admission=slack,
        host_watchdog_ns=watchdog_ns,
        link_timeout_ns=60_000_000_000,
        control_divider=divider,
    )
    core = BridgeCore(config, host_session=7)
    assert first_feedback(device, core, 1.0, "memory") is None
    loop = BridgeLoop(BridgeCounters(), answerer, changes)
    loop.attach(core, device, RunTally(core.config.period_ns))
    return loop, board


def tick(loop: BridgeLoop, board: MemoryBoard) -> Tick | None:
    board.tick()
    reading = loop.read()
    assert reading is not None
    return loop.on_feedback(reading, time.monotonic_ns())


def test_with_an_answerer_each_feedback_is_answered_and_written_in_the_same_call() -> None:
    chain = Chain()
    loop, board = attached(chain)
    assert loop.core is not None
    loop.core.arm()
    answered = 0
    for _ in range(20):
        before = len(board.sent)
        result = tick(loop, board)
        if result is None or result.answered is None:
            continue
        answered += 1
        command = decode_command(board.sent[-1])
        assert len(board.sent) == before + 1  # the answer, and nothing else, went out within the call
        assert command.enabled and command.answers_seq == board.board.last_feedback.seq  # type: ignore[union-attr]
        assert result.answered == result.stamp_ns == loop.core.stamp_ns
    assert answered >= 10 and loop.core.state == BridgeState.ARMED
    assert board.board.output_codes() != (0, 0)
    assert loop.statistics.execution_us.count == answered


def test_the_topics_loop_publishes_the_sample_and_sends_a_command_when_it_arrives() -> None:
    loop, board = attached()
    assert loop.core is not None
    loop.core.arm()
    for _ in range(10):
        result = tick(loop, board)
        assert (
            result is not None and result.answered is None
        )  # no answerer: the controller answers on a topic
        before = len(board.sent)
        internals = loop.on_command(TORQUE, result.stamp_ns, time.monotonic_ns())
        assert internals is not None and len(board.sent) == before + 1
    assert decode_command(board.sent[-1]).enabled
    assert loop.on_command(TORQUE, 123, time.monotonic_ns()) is None  # answers no published stamp
    assert loop.counters.refused == {"unknown_stamp": 1}


def test_changes_wait_for_the_next_tick_and_apply_before_its_answer() -> None:
    chain, changes = Chain(), ChangeBuffer()
    changes.put(lambda: setattr(chain, "gain", 2.0))  # no loop runs: at once
    assert chain.gain == 2.0
    loop, board = attached(chain, changes)
    assert loop.core is not None and changes.running
    loop.core.arm()
    tick(loop, board)
    changes.put(lambda: setattr(chain, "gain", 3.0))
    assert chain.gain == 2.0  # handed over, not applied outside a tick
    calls = len(chain.calls)
    tick(loop, board)
    assert chain.calls[calls:] and all(gain == 3.0 for _, gain in chain.calls[calls:])
    loop.detach()
    assert not changes.running
    changes.put(lambda: setattr(chain, "gain", 4.0))
    assert chain.gain == 4.0


@pytest.mark.parametrize("failure", [ZeroDivisionError("a broken law"), "torque must be finite"])
def test_a_failing_answerer_is_a_host_fault_with_a_safe_frame_at_once(failure: Any) -> None:
    chain = Chain()
    loop, board = attached(chain)
    assert loop.core is not None
    loop.core.arm()
    for _ in range(5):
        tick(loop, board)
    assert board.board.output_codes() != (0, 0)
    chain.result = failure
    before = len(board.sent)
    result = tick(loop, board)
    assert result is not None and result.answered is None  # the sample only: nothing answered
    assert len(board.sent) == before + 1 and not decode_command(board.sent[-1]).enabled
    assert loop.fault_signalled and "control chain failed" in loop.host_fault
    assert loop.fault() == f"host fault ({loop.host_fault})" and loop.core.state == BridgeState.DISARMED


def test_a_refused_answer_sends_the_core_frame_and_the_host_watchdog_nulls() -> None:
    chain = Chain()
    loop, board = attached(chain, watchdog_ns=10_000_000)
    assert loop.core is not None
    loop.core.arm()
    for _ in range(5):
        tick(loop, board)
    chain.result = None  # the chain refuses (a stale stamp, an implausible measurement)
    result = tick(loop, board)
    assert result is not None and result.answered is None and not loop.host_fault
    time.sleep(0.02)  # past the host watchdog (10 ms): at least this long, whatever the machine's load
    tick(loop, board)
    assert not decode_command(board.sent[-1]).enabled and loop.core.watchdog_trips >= 1


def test_the_rehearsal_publishes_what_the_run_publishes_stamped_an_hour_ahead_and_sends_no_output() -> None:
    """Each rehearsed tick steps the chain and gives the run's tick (its answer to publish), 1 h ahead."""
    chain = Chain()
    loop, board = attached(chain)
    assert loop.core is not None
    loop.rehearsal = RehearsalRecorder(loop.core.config.period_ns)
    rehearsed = []
    for _ in range(10):
        result = tick(loop, board)
        assert result is not None, "the rehearsal publishes every control tick, as the run does"
        stamp = loop.core.stamp_ns + REHEARSAL_STAMP_OFFSET_NS
        assert result.stamp_ns == stamp and result.answered == stamp  # joint_states, the answer, internals
        assert chain.calls[-1][0] == stamp  # the chain's outputs carry the stamp ahead too
        rehearsed.append(result)
    assert len(chain.calls) == 10
    assert all(not decode_command(frame).enabled for frame in board.sent)  # output never enabled
    recorder = loop.end_rehearsal()
    assert recorder is not None and chain.forgotten == 1 and loop.rehearsal is None
    assert len(recorder._answers) == 10
    loop.core.arm()
    run = [result for _ in range(10) if (result := tick(loop, board)) is not None]
    assert run and all(result.stamp_ns == result.answered for result in run if result.answered is not None)
    # nothing of the rehearsal reads as a sample of the run: the run's stamps are the board's, an hour behind
    assert all(r.stamp_ns - run[-1].stamp_ns >= REHEARSAL_STAMP_OFFSET_NS - 20_000_000 for r in rehearsed)
    assert all(result.stamp_ns < REHEARSAL_STAMP_OFFSET_NS for result in run)


def test_the_rehearsal_publishes_only_control_ticks_as_the_run_does() -> None:
    chain = Chain()
    loop, board = attached(chain, divider=2)
    assert loop.core is not None
    loop.rehearsal = RehearsalRecorder(loop.core.config.period_ns, divider=2)
    published = [tick(loop, board) for _ in range(10)]
    assert sum(result is not None for result in published) == 5 == len(chain.calls)


def test_a_chain_that_raises_while_rehearsing_is_a_host_fault_and_publishes_no_answer() -> None:
    chain = Chain()
    chain.result = ZeroDivisionError("a broken law")
    loop, board = attached(chain)
    assert loop.core is not None
    loop.rehearsal = RehearsalRecorder(loop.core.config.period_ns)
    result = tick(loop, board)
    assert result is not None and result.answered is None and "control chain failed" in loop.host_fault
    assert not decode_command(board.sent[-1]).enabled


def test_the_topics_loop_rehearsal_publishes_stamps_an_hour_ahead_and_times_the_answers() -> None:
    loop, board = attached()
    assert loop.core is not None
    loop.rehearsal = RehearsalRecorder(loop.core.config.period_ns)
    result = tick(loop, board)
    assert result is not None and result.stamp_ns == loop.core.stamp_ns + REHEARSAL_STAMP_OFFSET_NS
    before = len(board.sent)
    internals = loop.on_command(TORQUE, result.stamp_ns, time.monotonic_ns())
    assert internals is not None and internals["enabled"].tolist() == [0.0, 0.0]  # published, as in the run
    assert len(board.sent) == before and loop.rehearsal._answers  # timed, never sent


def test_detach_hands_on_what_the_device_could_not_do_to_make_the_valves_safe() -> None:
    loop, _ = attached()
    assert loop.device is not None
    loop.device.make_safe = lambda: "could not tell valve alpha (node 1) DISABLED"  # type: ignore[method-assign]
    assert loop.detach() == "could not tell valve alpha (node 1) DISABLED"
    assert loop.device is None and loop.detach() is None  # detached: nothing more to say


def test_first_feedback_says_why_none_came() -> None:
    class Speaks(Device):
        description = FrameDevice("x", MemoryBoard).description

        def open(self) -> None: ...
        def close(self) -> None: ...
        def write(self, command: CommandFrame) -> None: ...
        def make_safe(self) -> None: ...

        def read(self, timeout_s: float) -> Any:
            time.sleep(min(timeout_s, 0.01))
            return Reason.VERSION

    core = BridgeCore(BridgeConfig(), host_session=3)
    why = first_feedback(Speaks(), core, 0.05, "10.0.0.2:50101")
    assert why is not None and "another protocol version from 10.0.0.2:50101" in why
    assert core.rejected[Reason.VERSION] >= 1


def test_link_transport_names_a_row_of_the_device_table(monkeypatch: pytest.MonkeyPatch) -> None:
    from smm_schema.fields import config_fields

    (transport,) = (item for item in config_fields(LinkConfig) if item.name == "transport")
    assert transport.choices == device_names() == tuple(DEVICES) == ("udp", "serial", "canopen")
    with pytest.raises(
        ValueError, match=r"transport must be one of \('udp', 'serial', 'canopen'\), got 'can'"
    ):
        LinkConfig(transport="can")
    monkeypatch.setitem(DEVICES, "memory", "hw_bridge.test_loop:memory_device")  # type: ignore[index]
    device = open_device(LinkConfig(transport="memory"), CanopenConfig(), BridgeConfig())
    try:
        reading = device.read(0.0)
        assert reading is not None and not isinstance(reading, Reason) and reading.tick == 0
    finally:
        device.close()
