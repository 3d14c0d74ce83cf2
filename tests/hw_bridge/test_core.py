"""Bridge logic against hand-made feedback: arming, sessions, watchdog, stale refusal, limits, e-stop."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeError, BridgeState, Refusal
from smm_hw_bridge.encoder import EncoderConfig
from smm_hw_bridge.pressure import PressureConfig, measured_torque
from smm_hw_bridge.protocol import CommandFlag, FaultBit, FeedbackFrame, Reason, StatusBit, encode
from smm_hw_bridge.valve_output import ValveOutputConfig
from udp_bench import feedback_frame

HOST = 0x0000BEEF
BOARD = 0x12345678
MS = 1_000_000
CPR = 1 << 16
CONFIG = BridgeConfig(
    encoder=EncoderConfig(counts_per_rev=(CPR, CPR)),
    valve=ValveOutputConfig(
        gain=(1000.0, 1000.0), rate_limit=(math.inf, math.inf), time_constants=(0.0, 0.0)
    ),
    host_watchdog_ns=10 * MS,
    stale_periods=5,
    validity_ticks=10,
    soft_limits=(1.0, 1.0),
)


class Board:
    """Feeds a core with in-order feedback frames at 1 kHz of host time."""

    def __init__(self, core: BridgeCore, session: int = BOARD) -> None:
        self.core = core
        self.session = session
        self.seq = 0
        self.tick = 0
        self.now = 0
        self.status = int(StatusBit.HOST_LOCKED)
        self.faults = 0
        self.counts = (0, 0)
        self.host = HOST

    def frame(self, **changes: object) -> FeedbackFrame:
        self.seq += 1
        fields: dict[str, object] = {
            "session": self.session,
            "seq": self.seq,
            "tick": self.tick,
            "host_session": self.host,
            "counts": self.counts,
            "status": self.status,
            "faults": self.faults,
            **changes,
        }
        return feedback_frame(**fields)  # type: ignore[arg-type]

    def step(self, **changes: object) -> FeedbackFrame | None:
        frame = self.frame(**changes)
        admitted = self.core.on_datagram(encode(frame), self.now)
        self.tick += 1
        self.now += MS
        return admitted

    @property
    def stamp(self) -> int:
        return self.core.stamp_ns


def armed_core(config: BridgeConfig = CONFIG) -> tuple[BridgeCore, Board]:
    core = BridgeCore(config, HOST)
    board = Board(core)
    board.step()
    core.arm()
    board.step()
    assert core.on_command([0.5, -0.25], board.stamp, board.now) is None
    assert core.state == BridgeState.ARMED
    return core, board


def test_first_feedback_adopts_the_session_and_frames_are_safe() -> None:
    core = BridgeCore(CONFIG, HOST)
    assert core.next_frame(0) is None  # nothing to address yet
    board = Board(core)
    assert board.step() is not None
    assert core.state == BridgeState.DISARMED and core.board_session == BOARD
    frame = core.next_frame(board.now)
    assert frame is not None
    assert (frame.flags, frame.codes, frame.board_session, frame.session) == (0, (0, 0), BOARD, HOST)
    assert core.supply_pressure_bar == pytest.approx(1638 * 25 / 4095)


def test_arming_needs_feedback_after_activation_and_a_command_answering_it() -> None:
    core = BridgeCore(CONFIG, HOST)
    with pytest.raises(BridgeError):
        core.arm()
    board = Board(core)
    board.step()
    before = board.stamp
    core.arm()
    assert core.state == BridgeState.ARMING
    assert core.on_command([1.0, 1.0], before, board.now) is Refusal.BEFORE_ARM
    assert core.next_frame(board.now).flags == 0  # type: ignore[union-attr]
    board.step(host_session=0)  # the board has not locked to this host yet
    assert core.on_command([1.0, 1.0], board.stamp, board.now) is None
    assert core.state == BridgeState.ARMING
    board.step()
    assert core.on_command([1.0, -2.0], board.stamp, board.now) is None
    assert core.state == BridgeState.ARMED
    frame = core.next_frame(board.now)
    assert frame is not None and frame.flags == CommandFlag.ENABLE and frame.codes == (1000, -2000)
    assert frame.answers_seq == board.seq and frame.validity == 10


def test_a_measurement_answered_twice_moves_the_rate_limited_output_once() -> None:
    # lockstep: the board re-sends a feedback not yet answered and the host may answer it twice
    config = dataclasses.replace(
        CONFIG, valve=dataclasses.replace(CONFIG.valve, rate_limit=(1e6, 1e6))  # 1000 codes per ms
    )
    core, board = armed_core(config)
    board.step()
    first = core.on_command([10.0, -10.0], board.stamp, board.now), core.next_frame(board.now)
    again = core.on_command([10.0, -10.0], board.stamp, board.now), core.next_frame(board.now)
    assert first[0] is None and again[0] is None
    assert first[1] is not None and again[1] is not None
    assert again[1].codes == first[1].codes == (1500, -1250)  # from (500, -250): one step of 1000
    board.step()
    assert core.on_command([10.0, -10.0], board.stamp, board.now) is None
    assert core.next_frame(board.now).codes == (2500, -2250)  # type: ignore[union-attr]


def test_commands_are_refused_when_invalid_unknown_or_stale() -> None:
    core, board = armed_core()
    assert core.on_command([math.nan, 0.0], board.stamp, board.now) is Refusal.INVALID
    assert core.on_command([1.0], board.stamp, board.now) is Refusal.INVALID
    assert core.on_command([1.0, 1.0], board.stamp + 1, board.now) is Refusal.UNKNOWN_STAMP
    assert core.on_command([1.0, 1.0], board.stamp + 10 * MS, board.now) is Refusal.UNKNOWN_STAMP
    old = board.stamp
    for _ in range(5):
        board.step()
    assert core.on_command([1.0, 1.0], old, board.now) is None  # exactly K = 5 periods old: accepted
    board.step()
    assert core.on_command([1.0, 1.0], old, board.now) is Refusal.STALE
    assert core.refused[Refusal.STALE] == 1 and core.refused[Refusal.INVALID] == 2


def test_host_watchdog_sends_safe_output_when_commands_stop() -> None:
    core, board = armed_core()
    assert core.next_frame(board.now).flags == CommandFlag.ENABLE  # type: ignore[union-attr]
    assert core.next_frame(board.now + 10 * MS).flags == CommandFlag.ENABLE  # type: ignore[union-attr]
    late = core.next_frame(board.now + 10 * MS + 1)
    assert late is not None and late.flags == 0 and late.codes == (0, 0)
    assert core.watchdog_trips == 1
    board.step()
    assert core.on_command([0.1, 0.1], board.stamp, board.now) is None  # a fresh command resumes
    assert core.next_frame(board.now).codes == (100, 100)  # type: ignore[union-attr]


def test_a_command_past_its_validity_on_the_host_is_not_sent() -> None:
    core, board = armed_core()
    for _ in range(11):
        board.step()  # feedback keeps coming, no command answers it
    frame = core.next_frame(board.now - 10 * MS)
    assert frame is not None and frame.flags == 0


def test_soft_limits_cut_torque_into_the_zone_and_pass_torque_out_of_it() -> None:
    core, board = armed_core()
    board.counts = (round(1.05 / (2 * math.pi) * CPR), (-round(1.05 / (2 * math.pi) * CPR)) % (1 << 32))
    board.step()
    assert core.on_command([2.0, -2.0], board.stamp, board.now) is None
    assert core.next_frame(board.now).codes == (0, 0)  # type: ignore[union-attr]
    assert core.internals["limit_cut"].tolist() == [1.0, 1.0]
    board.step()
    assert core.on_command([-2.0, 2.0], board.stamp, board.now) is None
    assert core.next_frame(board.now).codes == (-2000, 2000)  # type: ignore[union-attr]
    assert core.internals["limit_cut"].tolist() == [0.0, 0.0]


def test_duplicate_out_of_order_stale_and_foreign_feedback_is_dropped_and_counted() -> None:
    core, board = armed_core()
    good = board.frame()
    assert core.on_datagram(encode(good), board.now) is not None
    assert core.on_datagram(encode(good), board.now) is None
    older = board.frame(seq=good.seq - 1)
    assert core.on_datagram(encode(older), board.now) is None
    board.tick, board.now = good.tick + 1, board.now + MS
    assert board.step(session=0x0BADF00D) is None  # one foreign frame: counted, session kept
    assert core.board_session == BOARD
    board.now += 50 * MS  # the next frame arrives 50 ms late behind a host stall
    assert board.step() is None
    assert core.rejected[Reason.DUPLICATE] == 1
    assert core.rejected[Reason.OUT_OF_ORDER] == 1
    assert core.rejected[Reason.SESSION] == 1
    assert core.rejected[Reason.STALE] == 1
    assert core.on_datagram(b"garbage", board.now) is None
    assert core.rejected[Reason.LENGTH] == 1


@pytest.mark.parametrize("joint", [0, 1])
def test_counts_wider_than_counter_bits_are_dropped_as_field_before_any_use(joint: int) -> None:
    bits = 24
    config = dataclasses.replace(CONFIG, encoder=dataclasses.replace(CONFIG.encoder, counter_bits=bits))
    fresh = BridgeCore(config, HOST)
    wide = Board(fresh).frame(counts=(1 << bits, 0) if joint == 0 else (0, 1 << bits))
    assert fresh.on_datagram(encode(wide), 0) is None  # the very first frame: no session adopted
    assert (fresh.state, fresh.board_session, fresh.last_rejection) == (
        BridgeState.DISCONNECTED,
        None,
        Reason.FIELD,
    )
    core, board = armed_core(config)
    board.counts = (1000, -1000 % (1 << bits))
    assert board.step() is not None

    def snapshot() -> tuple[object, ...]:
        return (core.state, core.position_floats, core.stamp_ns, core.last_feedback, core.stats.received)

    before, received, position = snapshot(), core.stats.received, core.position_floats
    counts = list(board.counts)
    counts[joint] = 1 << bits
    frame = board.frame(counts=tuple(counts), tick=board.tick)
    board.seq -= 1  # the next good frame reuses this seq: a rejected frame must not have moved admission
    assert core.on_datagram(encode(frame), board.now) is None
    assert core.last_rejection is Reason.FIELD and core.rejected[Reason.FIELD] == 1
    assert snapshot() == before
    board.counts = ((1 << bits) - 1, 0)  # the widest count that fits
    assert board.step() is not None and core.last_rejection is None
    assert core.state == BridgeState.ARMED and core.stats.received == received + 1
    assert core.position_floats[0] < position[0]  # 1000 -> 2**24 - 1: unwrapped backwards, not wrapped
    assert dict(core.rejected) == {Reason.FIELD: 1}


def test_loss_and_longest_streak_from_sequence_gaps() -> None:
    core, board = armed_core()
    board.seq += 3
    board.step()
    board.seq += 1
    board.step()
    assert (core.stats.lost, core.stats.longest_streak) == (4, 3)
    assert 0 < core.stats.loss_fraction < 1


def test_board_reboot_disables_output_until_reactivation_and_old_commands_never_pass() -> None:
    core, board = armed_core()
    pre_break = board.stamp
    assert core.on_command([1.0, 1.0], pre_break, board.now) is None
    reboot = Board(core, session=0x0A0A0A0A)
    reboot.now = board.now
    for _ in range(CONFIG.reboot_frames):
        reboot.step()
    assert core.state == BridgeState.SESSION_LOST and core.reboots == 1
    assert core.board_session == 0x0A0A0A0A
    assert core.stamp_ns > pre_break  # stamps continue across sessions
    frame = core.next_frame(reboot.now)
    assert frame is not None and frame.flags == 0 and frame.board_session == 0x0A0A0A0A
    assert core.on_command([1.0, 1.0], pre_break, reboot.now) is Refusal.INACTIVE
    core.arm()
    assert core.on_command([1.0, 1.0], pre_break, reboot.now) is Refusal.UNKNOWN_STAMP
    reboot.step()
    assert core.on_command([0.3, 0.3], core.stamp_ns, reboot.now) is None
    assert core.next_frame(reboot.now).codes == (300, 300)  # type: ignore[union-attr]


def test_link_loss_while_armed_needs_reactivation() -> None:
    core, board = armed_core()
    assert core.next_frame(board.now + 101 * MS).flags == 0  # type: ignore[union-attr]
    assert core.state == BridgeState.SESSION_LOST
    board.now += 101 * MS
    board.step()
    assert core.on_command([1.0, 1.0], board.stamp, board.now) is Refusal.INACTIVE
    core.arm()
    assert core.state == BridgeState.ARMING


def test_link_gap_while_arming_keeps_arming_and_the_output_goes_live_on_feedback_after_it() -> None:
    core = BridgeCore(CONFIG, HOST)
    board = Board(core)
    board.step()
    core.arm()
    before_gap = board.stamp
    assert core.next_frame(board.now + 101 * MS).flags == 0  # type: ignore[union-attr]
    assert core.state == BridgeState.ARMING  # nothing was live: a start-up stall is no lost session
    board.tick += 101  # the board ticked on; none of it reached the host
    board.now += 101 * MS
    assert board.step() is not None
    assert core.on_command([1.0, 1.0], before_gap, board.now) is not None  # answers feedback before the gap
    assert core.on_command([0.5, -0.25], board.stamp, board.now) is None
    assert core.state == BridgeState.ARMED
    assert core.next_frame(board.now).flags == CommandFlag.ENABLE  # type: ignore[union-attr]


def test_estop_latches_until_rearm_and_the_board_confirms() -> None:
    core, board = armed_core()
    core.estop()
    frame = core.next_frame(board.now)
    assert frame is not None and frame.flags == CommandFlag.ESTOP and frame.codes == (0, 0)
    with pytest.raises(BridgeError):
        core.arm()
    board.status |= StatusBit.ESTOP_LATCHED
    board.step()
    assert core.on_command([1.0, 1.0], board.stamp, board.now) is Refusal.INACTIVE
    core.rearm()
    assert core.next_frame(board.now).flags == CommandFlag.REARM  # type: ignore[union-attr]
    board.step()
    assert core.state == BridgeState.ESTOP  # the board still reports its latch
    board.status &= ~StatusBit.ESTOP_LATCHED
    board.step()
    assert core.state == BridgeState.ARMING
    board.step()
    assert core.on_command([1.0, 1.0], board.stamp, board.now) is None
    assert core.state == BridgeState.ARMED


def test_board_side_estop_and_fault_bits_force_safe_output() -> None:
    core, board = armed_core()
    board.step(status=int(StatusBit.HOST_LOCKED | StatusBit.ESTOP_LATCHED))
    assert core.state == BridgeState.ESTOP
    core2, board2 = armed_core()
    board2.faults = int(FaultBit.VALVE_DRIVER)
    board2.step()
    assert core2.state == BridgeState.FAULT
    assert core2.next_frame(board2.now).flags == 0  # type: ignore[union-attr]
    with pytest.raises(BridgeError):
        core2.arm()
    with pytest.raises(BridgeError):
        core2.rearm()


def test_disarm_sends_safe_output() -> None:
    core, board = armed_core()
    core.disarm()
    assert core.state == BridgeState.DISARMED
    assert core.next_frame(board.now).flags == 0  # type: ignore[union-attr]
    assert core.on_command([1.0, 1.0], board.stamp, board.now) is Refusal.INACTIVE


def test_applied_torque_is_the_torque_of_the_codes_the_board_reports() -> None:
    core, board = armed_core()
    board.step(output_codes=(500, -1500))
    np.testing.assert_allclose(core.applied_torque, [0.5, -1.5])


def test_applied_torque_goes_through_the_valve_lag_model() -> None:
    rise, fall = 0.02, 0.01
    valve = ValveOutputConfig(
        gain=(1000.0, 1000.0), rate_limit=(math.inf, math.inf), time_constants=(rise, fall)
    )
    core, board = armed_core(dataclasses.replace(CONFIG, valve=valve))
    h = 1e-3
    # Opening from null: the torque over tick k is the mean of target (1 - e^{-t/T_rise}) over that tick.
    target = np.array([0.5, -1.5])
    for k in range(1, 4):
        board.step(output_codes=(500, -1500))
        integral = h - rise * (np.exp(-(k - 1) * h / rise) - np.exp(-k * h / rise))
        np.testing.assert_allclose(core.applied_torque, target * integral / h, rtol=1e-12)
    # Back to null: it closes with T_fall from where it was.
    reached = target * (1.0 - np.exp(-3 * h / rise))
    board.step(output_codes=(0, 0))
    np.testing.assert_allclose(
        core.applied_torque, reached * fall / h * (1.0 - np.exp(-h / fall)), rtol=1e-12
    )
    with pytest.raises(ValueError, match="time_constants"):
        ValveOutputConfig(time_constants=(0.02, 0.0))


def test_measured_torque_is_the_load_pressure_of_channels_1_and_2_times_lever_arm_area() -> None:
    pressure = PressureConfig(
        bar_per_code=(0.01, -0.02), zero_code=(2000.0, 2100.0), lever_arm_area=(2e-5, 1e-5)
    )
    core, board = armed_core(dataclasses.replace(CONFIG, pressure=pressure))
    board.step(adc=(1638, 2500, 1900, 2048))
    # (code - zero) * bar/code * 1e5 Pa/bar * m^3: 500 * 0.01 * 1e5 * 2e-5 = 10; -200 * -0.02 * 1e5 * 1e-5 = 4
    np.testing.assert_allclose(core.measured_torque, [10.0, 4.0], rtol=1e-12)
    np.testing.assert_allclose(core.measured_torque, measured_torque((1638, 2500, 1900, 2048), pressure))
    np.testing.assert_allclose(core.internals["measured_torque"], [10.0, 4.0], rtol=1e-12)
    board.step(adc=(1638, 2000, 2100, 0))  # channel 3 is not a load channel
    assert core.measured_torque.tolist() == [0.0, 0.0]


def test_invalid_bridge_configs_are_rejected() -> None:
    for kwargs in (
        {"pressure": 3},
        {"limit_stop_margin": 0.0},
        {"limit_stop_lead": -0.01},
        {"stale_periods": 0},
        {"validity_ticks": 70000},
        {"soft_limits": (0.0, 1.0)},
        {"encoder": 3},
    ):
        with pytest.raises(ValueError):
            BridgeConfig(**kwargs)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        BridgeCore(CONFIG, 0)
