"""The board core: command validity, hold, watchdog null, host lock, e-stop latch, faults, sensors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from smm_bench_emulator.board import BoardConfig, BoardCore
from smm_hw_bridge.protocol import (
    CommandFlag,
    CommandFrame,
    FaultBit,
    FeedbackFrame,
    StatusBit,
    decode_feedback,
    encode,
)
from smm_sim.plant import PlantConfig

HOST = 0x00C0FFEE
PLANT = PlantConfig(encoder_counts_per_rev=1 << 16)


def board(**kwargs: object) -> tuple[BoardCore, FeedbackFrame]:
    core = BoardCore(BoardConfig(plant=PLANT, adc_noise=0.0, **kwargs))  # type: ignore[arg-type]
    return core, decode_feedback(core.start())


class Host:
    """Sends commands answering the board's last feedback."""

    def __init__(self, core: BoardCore, session: int = HOST) -> None:
        self.core = core
        self.session = session
        self.seq = 0

    def send(
        self,
        flags: int = int(CommandFlag.ENABLE),
        codes: tuple[int, int] = (0, 0),
        validity: int = 5,
        fb: FeedbackFrame | None = None,
        board_session: int | None = None,
    ) -> CommandFrame | None:
        fb = fb or self.core.last_feedback
        assert fb is not None
        self.seq += 1
        frame = CommandFrame(
            self.session,
            self.seq,
            board_session or self.core.session,
            fb.seq,
            fb.tick,
            flags,
            validity,
            codes,
        )
        return self.core.receive(encode(frame))

    def lock(self) -> None:
        assert self.send(flags=0) is not None


def test_boot_feedback_and_reboot_changes_the_session() -> None:
    core, fb = board()
    assert (fb.tick, fb.seq, fb.host_session, fb.output_codes) == (0, 1, 0, (0, 0))
    assert fb.session == core.session != 0
    first = core.session
    core.boot()
    assert core.session != first and core.tick == 0


def test_lockstep_applies_the_answer_over_the_next_interval() -> None:
    core, _ = board(full_scale_torque=(10.0, 5.0))
    host = Host(core)
    host.lock()
    assert core.answered
    fb = decode_feedback(core.tick_lockstep())
    host.send(codes=(3276, -32767))
    assert core.answered
    fb = decode_feedback(core.tick_lockstep())
    assert fb.output_codes == (3276, -32767) and fb.status & StatusBit.ENABLED
    assert fb.applied_seq == host.seq and fb.applied_age == 1
    assert core.valve_torque() == pytest.approx((3276 / 32767 * 10.0, -5.0))
    assert core.applied_log[-1][1:] == (host.seq, (3276, -32767))


def test_realtime_hold_then_null_at_the_first_tick_past_validity() -> None:
    core, _ = board()
    host = Host(core)
    host.lock()
    core.tick_realtime()
    host.send(codes=(1000, 1000), validity=5)  # answers tick 1
    answered_tick = core.tick
    fb = decode_feedback(core.tick_realtime())  # latched at tick 2
    assert fb.output_codes == (1000, 1000) and not fb.status & StatusBit.HOLDING
    outputs = []
    while core.tick < answered_tick + 8:
        fb = decode_feedback(core.tick_realtime())
        outputs.append((fb.tick, fb.output_codes, fb.status))
    held = [tick for tick, codes, _ in outputs if codes == (1000, 1000)]
    assert held[-1] == answered_tick + 5  # held while valid ...
    null = [tick for tick, codes, status in outputs if codes == (0, 0)]
    assert null[0] == answered_tick + 6  # ... null on the first tick past validity
    assert all(
        status & StatusBit.WATCHDOG and not status & StatusBit.ENABLED
        for _, c, status in outputs
        if c == (0, 0)
    )
    assert fb.late_commands == 5  # ticks 3..7 held while the answer to the previous feedback was missing
    assert core.enabled_ticks == 6  # the latch at tick 2 and the five late ticks (the last one nulls)


def test_watchdog_ramp_reaches_null_in_ramp_ticks() -> None:
    core, _ = board(ramp_ticks=4)
    host = Host(core)
    host.lock()
    core.tick_realtime()
    host.send(codes=(32767, -16000), validity=1)
    codes = [decode_feedback(core.tick_realtime()).output_codes for _ in range(7)]
    assert codes[0] == (32767, -16000)  # tick 2: answer to tick 1, valid for 1 tick
    assert [c[0] for c in codes[1:5]] == [round(32767 * k / 4) for k in (3, 2, 1, 0)]
    assert codes[2][1] == 0  # each joint ramps at full scale / ramp_ticks per tick
    assert codes[4] == codes[5] == codes[6] == (0, 0)


def test_expired_or_future_commands_are_never_applied() -> None:
    core, fb0 = board()
    host = Host(core)
    host.lock()
    for _ in range(10):
        core.tick_realtime()
    dropped = core.dropped_frames
    assert host.send(codes=(500, 500), validity=3, fb=fb0) is None
    future = FeedbackFrame(**{**fb0.__dict__, "seq": 999, "tick": 999})
    assert host.send(codes=(500, 500), fb=future) is None
    assert core.dropped_frames == dropped + 2
    assert decode_feedback(core.tick_realtime()).output_codes == (0, 0)
    assert all(codes != (500, 500) for _, _, codes in core.applied_log)


def test_a_new_host_must_lock_with_a_disabled_frame_and_takes_over_at_null() -> None:
    core, _ = board()
    intruder = Host(core, session=0x99)
    assert intruder.send(codes=(100, 100)) is None  # enabled frame from a host never seen
    host = Host(core)
    host.lock()
    host.send(codes=(100, 100))
    core.tick_lockstep()
    assert core.output_codes() == (100, 100)
    assert intruder.send(codes=(7, 7)) is None  # the board is locked to HOST
    new_bridge = Host(core, session=0x77)
    new_bridge.lock()  # reconfigured bridge: new host session, output to null at once
    assert core.output_codes() == (0, 0) and core.host_session == 0x77
    assert host.send(codes=(100, 100)) is None  # the old session's in-flight commands are dropped


def test_wrong_board_session_duplicates_and_crc_errors_are_dropped_and_counted() -> None:
    core, _ = board()
    host = Host(core)
    host.lock()
    assert host.send(codes=(1, 1), board_session=0x1234) is None
    frame = CommandFrame(HOST, host.seq + 1, core.session, 1, 0, 1, 5, (2, 2))
    data = encode(frame)
    assert core.receive(data) is not None
    assert core.receive(data) is None  # duplicate
    assert core.receive(data[:-1] + bytes([data[-1] ^ 1])) is None
    assert (core.crc_errors, core.dropped_frames) == (1, 2)


def test_estop_latches_until_rearm_from_the_locked_host() -> None:
    core, _ = board()
    host = Host(core)
    host.lock()
    host.send(codes=(900, 900))
    core.tick_lockstep()
    assert core.output_codes() == (900, 900)
    Host(core, session=0x55).send(flags=int(CommandFlag.ESTOP))  # any sender may stop
    assert core.estop_latched and core.output_codes() == (0, 0)
    host.send(codes=(900, 900))
    fb = decode_feedback(core.tick_lockstep())
    assert fb.output_codes == (0, 0) and fb.status & StatusBit.ESTOP_LATCHED
    host.send(flags=int(CommandFlag.REARM))
    assert not core.estop_latched
    host.send(codes=(900, 900))
    assert decode_feedback(core.tick_lockstep()).output_codes == (900, 900)


def test_fault_bits_and_low_supply_null_the_valves() -> None:
    core, _ = board()
    host = Host(core)
    host.lock()
    host.send(codes=(900, 900))
    core.tick_lockstep()
    core.set_faults(int(FaultBit.VALVE_DRIVER))
    host.send(codes=(900, 900))
    fb = decode_feedback(core.tick_lockstep())
    assert fb.faults == FaultBit.VALVE_DRIVER and fb.output_codes == (0, 0)
    core.set_faults(0)
    core.supply_pressure = 3.0
    host.send(codes=(900, 900))
    fb = decode_feedback(core.tick_lockstep())
    assert fb.faults == FaultBit.SUPPLY_LOW and fb.output_codes == (0, 0)
    assert fb.adc[0] == round(3.0 / (25 / 4095))


def test_encoder_counts_offset_direction_and_wrap() -> None:
    core, _ = board(zero_offset=(10, 5), direction=(1, -1), counter_bits=16)
    core.plant.reset([0.1, 0.2])
    quantum = 2 * math.pi / PLANT.encoder_counts_per_rev
    counts = core.counts()
    assert counts == ((10 + round(0.1 / quantum)) % 65536, (5 - round(0.2 / quantum)) % 65536)


def test_valve_deadband_and_supply_scale_the_torque() -> None:
    core, _ = board(valve_deadband=(1000.0, 0.0), supply_pressure=2.5, supply_low=0.0)
    core.output = [11000.0, -32767.0]
    assert core.valve_torque() == pytest.approx((10000 / 32767 * 10 * 0.5, -10 * 0.5))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"plant": PlantConfig()},
        {"counter_bits": 7},
        {"direction": (0, 1)},
        {"full_scale_torque": (0.0, 1.0)},
        {"ramp_ticks": 0},
        {"nominal_pressure": 0.0},
    ],
)
def test_invalid_board_configs_are_rejected(kwargs: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        BoardConfig(**kwargs)  # type: ignore[arg-type]


def test_the_a_d_noise_is_the_seeded_generator_s_one_draw_per_tick() -> None:
    sigma, seed = 2.0, 11
    core = BoardCore(BoardConfig(plant=PLANT, adc_noise=sigma, seed=seed))
    drawn = [decode_feedback(core.tick_realtime()).adc for _ in range(2500)]  # past two blocks of draws
    reference = np.random.default_rng(seed)
    supply = 10.0 / (25.0 / 4095.0)
    for adc in drawn:
        expected = np.array([supply, 2048.0, 2048.0, 2048.0]) + reference.normal(0.0, sigma, 4)
        assert adc == tuple(int(min(max(round(v), 0), 4095)) for v in expected)
