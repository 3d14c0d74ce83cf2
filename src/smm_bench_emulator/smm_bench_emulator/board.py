"""The I/O board's firmware logic and the bench it drives, without sockets or clocks (pure, seeded).

``receive(bytes)`` takes command frames as they arrive; the tick functions advance the board one 1 kHz
tick and return the feedback frame to send. What the board does at each tick (docs/HW_PROTOCOL.md,
"Board behaviour") is in :meth:`BoardCore._latch`; the bench (plant, :mod:`.valve`, encoders, A/D) in
:meth:`BoardCore._advance` and :meth:`BoardCore._feedback`.
"""

from __future__ import annotations

import dataclasses
import math
import secrets
from dataclasses import dataclass, field

import numpy as np
from smm_hw_bridge.protocol import (
    ADC_MAX,
    CODE_MAX,
    NO_COMMAND_AGE,
    CommandFlag,
    CommandFrame,
    FaultBit,
    FeedbackFrame,
    ProtocolError,
    Reason,
    StatusBit,
    decode_command,
    encode,
    seq_newer,
    u32_diff,
)
from smm_sim.plant import PlantConfig, SimulatedPlant

from smm_bench_emulator.bench import BenchSettings, check_lock_stability
from smm_bench_emulator.valve import HydraulicValves

__all__ = ["BoardConfig", "BoardCore"]

_U32 = 1 << 32
_APPLIED_KEPT = 200_000
_NOISE_BLOCK = 1000
"""Ticks of A/D noise drawn at once (the same values as one draw per tick: the generator's order)."""


@dataclass(frozen=True)
class BoardConfig(BenchSettings):
    """The emulated bench: the plant and the truths of :class:`~smm_bench_emulator.bench.BenchSettings`.

    Attributes:
        plant: The SMM plant (smm_sim); its ``control_period`` is the board tick, its
            ``encoder_counts_per_rev`` (> 0) the encoders' resolution, its ``valve_time_constants`` the
            servo valves' first-order lag (run by the valve model, not by the plant).
    """

    plant: PlantConfig = field(
        default_factory=lambda: PlantConfig(
            encoder_counts_per_rev=1 << 20, valve_time_constants=(0.0217, 0.0109)
        )
    )

    def __post_init__(self) -> None:
        if not isinstance(self.plant, PlantConfig) or self.plant.encoder_counts_per_rev <= 0:
            raise ValueError("plant must be a PlantConfig with encoder_counts_per_rev > 0")
        super().__post_init__()
        check_lock_stability(self, self.plant)

    @property
    def period_ns(self) -> int:
        """Board tick (ns)."""
        return self.plant.period_ns


class BoardCore:
    """The board: session, host lock, command validity, hold, watchdog ramp, e-stop latch, fault bits.

    Args:
        config: The bench.
    """

    def __init__(self, config: BoardConfig) -> None:
        self._config = config
        self._rng = np.random.default_rng(config.seed)
        self._noise: list[list[float]] = []
        # the valve model runs the lag: the lock's torque must not pass through it
        self.plant = SimulatedPlant(dataclasses.replace(config.plant, valve_time_constants=None))
        self.valves = HydraulicValves(config, config.plant.valve_time_constants)
        self._quantum = 2.0 * math.pi / config.plant.encoder_counts_per_rev
        self.injected_faults = 0
        self.supply_pressure = config.supply_pressure
        """Supply pressure now (bar); tests and fault injection change it."""
        self.boots = 0
        self.applied_log: list[tuple[int, int, tuple[int, int]]] = []
        """(tick, command seq, codes) of every enabled command the board put on the valves, across boots."""
        self.boot()

    @property
    def config(self) -> BoardConfig:
        """The configuration."""
        return self._config

    def boot(self) -> None:
        """Power-on or reboot: new session, tick 0, counters 0, no host, valves null; the plant moves on."""
        self.boots += 1
        self.session = secrets.randbelow(_U32 - 1) + 1  # not from the seed: a restart must look new
        self.tick = 0
        self._fb_seq = 0
        self.host_session = 0
        self.late_commands = 0
        self.enabled_ticks = 0
        """Ticks latched with a command on the valves (the late fraction's denominator); not on the wire."""
        self.crc_errors = 0
        self.dropped_frames = 0
        self._last_cmd_seq: int | None = None
        self._inbox: CommandFrame | None = None
        self._active: CommandFrame | None = None
        self.output = [0.0, 0.0]
        self._ramping = False
        self._watchdog = False
        self._holding = False
        self.estop_latched = False
        self.last_feedback: FeedbackFrame | None = None

    # ---- receive ------------------------------------------------------------------------------------

    def receive(self, data: bytes) -> CommandFrame | None:
        """Takes one received datagram; returns the command if it was accepted for the next latch."""
        try:
            frame = decode_command(data)
        except ProtocolError as error:
            if error.reason is Reason.CRC:
                self.crc_errors = (self.crc_errors + 1) % _U32
            else:
                self.dropped_frames = (self.dropped_frames + 1) % _U32
            return None
        if frame.flags & CommandFlag.ESTOP:
            self._estop()  # honoured from any sender: stopping is always allowed
            return None
        if frame.board_session != self.session:
            self._drop()
            return None
        if frame.session != self.host_session:
            if frame.flags & CommandFlag.ENABLE:
                self._drop()  # a new host must first send a disabled frame
                return None
            self.host_session = frame.session  # a new host takes over: output to null
            self._last_cmd_seq = None
            self._inbox = None
            self._disable()
        last = self.last_feedback
        if (
            last is None
            or u32_diff(frame.answers_tick, last.tick) > 0
            or seq_newer(frame.answers_seq, last.seq)
        ):
            self._drop()  # answers a measurement never sent
            return None
        if u32_diff(self.tick, frame.answers_tick) > frame.validity:
            self._drop()  # expired: never applied
            return None
        if self._last_cmd_seq is not None and not seq_newer(frame.seq, self._last_cmd_seq):
            self._drop()  # duplicate or out of order
            return None
        self._last_cmd_seq = frame.seq
        if frame.flags & CommandFlag.REARM and self.estop_latched:
            self.estop_latched = False
        self._inbox = frame
        return frame

    def _drop(self) -> None:
        self.dropped_frames = (self.dropped_frames + 1) % _U32

    def _estop(self) -> None:
        self.estop_latched = True
        self._inbox = None
        self._disable()

    def _disable(self) -> None:
        self._active = None
        self._ramping = False
        self._holding = False
        self.output = [0.0, 0.0]

    def set_faults(self, bits: int) -> None:
        """Injects (or clears with 0) fault bits; any set bit nulls the valves."""
        self.injected_faults = int(bits) & 0xFFFF

    @property
    def faults(self) -> int:
        """Fault bits now: injected ones and SUPPLY_LOW."""
        low = FaultBit.SUPPLY_LOW if self.supply_pressure < self._config.supply_low else 0
        return self.injected_faults | int(low)

    # ---- tick ---------------------------------------------------------------------------------------

    def start(self) -> bytes:
        """The feedback of tick 0 (sent at boot)."""
        return self._feedback()

    def tick_realtime(self) -> bytes:
        """One real-time tick: move, sample, latch the latest valid command for the next period, send.

        The plant moves over the elapsed period with the valves as they were, so a command answering
        feedback k acts from tick k + 1 on.
        """
        expected = self._fb_seq
        self._advance()
        self.tick = (self.tick + 1) % _U32
        self._latch(expected)
        return self._feedback()

    def tick_lockstep(self) -> bytes:
        """One lockstep tick, taken when the answer to the last feedback has arrived: latch, move, sample."""
        self._latch(self._fb_seq)
        self._advance()
        self.tick = (self.tick + 1) % _U32
        return self._feedback()

    @property
    def answered_enabled(self) -> bool:
        """:attr:`answered` by an enabled command (a lockstep waiting for the controller, not safe frames)."""
        return self.answered and self._inbox is not None and self._inbox.enabled

    @property
    def answered(self) -> bool:
        """True if a command answering the last feedback frame waits in the inbox (lockstep's trigger)."""
        return self._inbox is not None and self._inbox.answers_seq == self._fb_seq

    def _latch(self, expected_seq: int) -> None:
        command, self._inbox = self._inbox, None
        self._holding = False
        if self.estop_latched or self.faults:
            self._disable()
            return
        if command is not None and u32_diff(self.tick, command.answers_tick) > command.validity:
            self.dropped_frames = (self.dropped_frames + 1) % _U32  # expired while waiting for the tick
            command = None
        if command is not None:
            if command.flags & CommandFlag.ENABLE:
                self._active = command
                self._ramping = self._watchdog = False
                self.output = [float(command.codes[0]), float(command.codes[1])]
                self.applied_log.append((self.tick, command.seq, command.codes))
                if len(self.applied_log) > _APPLIED_KEPT:
                    del self.applied_log[: _APPLIED_KEPT // 2]
            else:
                self._disable()
                self._watchdog = False
        if self._active is not None:
            self.enabled_ticks += 1
            if command is None or command.answers_seq != expected_seq:
                self.late_commands = (self.late_commands + 1) % _U32
        if command is None and self._active is not None:
            if u32_diff(self.tick, self._active.answers_tick) <= self._active.validity:
                self._holding = True
            else:
                self._active = None
                self._ramping = self._watchdog = True
        if self._ramping:
            step = CODE_MAX / self._config.ramp_ticks
            self.output = [math.copysign(max(abs(code) - step, 0.0), code) for code in self.output]
            if self.output == [0.0, 0.0]:
                self._ramping = False

    @property
    def status_enabled(self) -> bool:
        """True while an enabled command drives the valves."""
        return self._active is not None

    def output_codes(self) -> tuple[int, int]:
        """D/A codes on the valves now."""
        return round(self.output[0]), round(self.output[1])

    def valve_torque(self) -> tuple[float, float]:
        """Torque the open valves head for with the D/A codes now, before their lag (N m)."""
        return self.valves.target(self.output_codes(), self.supply_pressure)

    def _advance(self) -> None:
        enabled = self._active is not None or self._ramping
        self.valves.move(self.plant, self.output_codes(), enabled, self.supply_pressure)

    def counts(self) -> tuple[int, int]:
        """Raw encoder counters now."""
        alpha, beta, _, _ = self.plant.measure_floats()
        config = self._config
        raw = []
        for joint, angle in enumerate((alpha, beta)):
            count = round(angle / self._quantum)
            raw.append(
                (config.zero_offset[joint] + config.direction[joint] * count) % (1 << config.counter_bits)
            )
        return raw[0], raw[1]

    def _adc(self) -> tuple[int, int, int, int]:
        config = self._config
        sigma = config.adc_noise
        if sigma > 0 and not self._noise:
            self._noise = self._rng.normal(0.0, sigma, (_NOISE_BLOCK, 4)).tolist()[::-1]
        noise = self._noise.pop() if sigma > 0 else (0.0, 0.0, 0.0, 0.0)
        load = self.valves.load_pressure()
        values = [
            self.supply_pressure / config.bar_per_code,
            config.load_zero_code[0] + load[0] / config.load_bar_per_code[0],
            config.load_zero_code[1] + load[1] / config.load_bar_per_code[1],
            2048.0,
        ]
        return tuple(int(min(max(round(v + n), 0), ADC_MAX)) for v, n in zip(values, noise, strict=True))  # type: ignore[return-value]

    def _status(self) -> int:
        status = 0
        if self._active is not None:
            status |= StatusBit.ENABLED
        if self.estop_latched:
            status |= StatusBit.ESTOP_LATCHED
        if self._holding:
            status |= StatusBit.HOLDING
        if self._watchdog:
            status |= StatusBit.WATCHDOG
        if self.host_session:
            status |= StatusBit.HOST_LOCKED
        return int(status)

    def _feedback(self) -> bytes:
        self._fb_seq = (self._fb_seq + 1) % _U32
        active = self._active
        age = (
            NO_COMMAND_AGE
            if active is None
            else min(u32_diff(self.tick, active.answers_tick), NO_COMMAND_AGE)
        )
        frame = FeedbackFrame.trusted(  # every field below is kept in range by this class
            self.session,
            self._fb_seq,
            self.tick,
            self.host_session,
            self.counts(),
            self._adc(),
            self._status(),
            self.faults,
            0 if active is None else active.seq,
            age,
            self.output_codes(),
            self.late_commands,
            self.crc_errors,
            self.dropped_frames,
        )
        self.last_feedback = frame
        return encode(frame)
