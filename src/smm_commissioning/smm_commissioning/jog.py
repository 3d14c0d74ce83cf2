"""``jog``: one joint at a time, small open-loop code pulses inside a window; the valve and encoder's truths.

A search steps the code out from 0 on each side until the measured torque answers, a staircase follows; a
line through each side's settled torques gives its onset and torque per code: null bias, deadband, gain per
direction, polarity; the motion under the torque gives the encoder's direction. docs/COMMISSIONING.md, "jog".
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
from smm_hw_bridge.encoder import EncoderConfig
from smm_hw_bridge.pressure import PressureConfig
from smm_hw_bridge.protocol import CODE_MAX, StatusBit
from smm_schema.ranges import above, bounds, check_bounds

from smm_commissioning.errors import MotionStopError
from smm_commissioning.host import BenchHost
from smm_commissioning.probe import JOINTS, signed_counts

__all__ = ["JogConfig", "JointJog", "Pulse", "PulseRun", "jog_joint", "run_jog"]

_MIN_DISPLACEMENT = 20
"""Counts a pulse must move its joint for its direction to count (above the encoder's rest noise)."""
_OUTWARD = 40
"""Counts a joint past the window must move outwards over 10 ticks for the pulse to be cut (the encoder's
rest noise stays below it): a pulse that brings it back runs."""
_HELD_DRIFT = 0.5
"""Fraction of the window the joint not jogged may drift while its valve is held at code 0, its null not
yet known: past it that valve is open at code 0 and its joint is jogged first."""


class _HeldJointOpenError(MotionStopError):
    """The joint not jogged drifted at code 0 before its own jog: its null bias is past its overlap."""


@dataclass(frozen=True)
class JogConfig:
    """How ``jog`` moves a joint and what stops it.

    Attributes:
        window: Largest excursion from the start (rad), in (0, 0.5]: past it the valves are disabled at once.
        velocity_limit: Largest speed (rad/s), > 0: past it the valves are disabled at once.
        pulse_ticks: Ticks one code is held, in [20, 2000].
        average_ticks: Last ticks of a pulse whose torque is averaged, in [5, pulse_ticks).
        rest_ticks: Ticks the valves stay disabled between pulses, in [1, 10000].
        search_step: Code step of the search from 0 outwards (codes), in [10, 5000].
        search_max: Largest |code| the search tries (codes), in [100, 32767].
        stair_step: Code step of the staircase past the onset (codes), in [10, 5000].
        stair_levels: Levels of the staircase per side, in [1, 20].
        open_torque: A settled torque above this means the valve opened (N m), > 0.
        counting_torque: A pulse above this torque that moves its joint by less than 20 counts means the
            encoder does not count; the encoder's direction is taken from pulses above it (gravity and
            friction cannot turn the motion against it) (N m), > 0.
        tick_period: Board tick (s), > 0.
        encoder: Counts per revolution and counter width (``bridge.encoder.*``).
        pressure: Calibration of the load-pressure channels (``bridge.pressure.*``).
    """

    window: float = field(default=0.2, metadata=bounds(0.0, 0.5, low_open=True))
    velocity_limit: float = field(default=1.5, metadata=above(0.0))
    pulse_ticks: int = field(default=150, metadata=bounds(20, 2000))
    average_ticks: int = field(default=60, metadata=bounds(5, 1999))
    rest_ticks: int = field(default=60, metadata=bounds(1, 10_000))
    search_step: int = field(default=150, metadata=bounds(10, 5000))
    search_max: int = field(default=6000, metadata=bounds(100, CODE_MAX))
    stair_step: int = field(default=150, metadata=bounds(10, 5000))
    stair_levels: int = field(default=8, metadata=bounds(1, 20))
    open_torque: float = field(default=0.06, metadata=above(0.0))
    counting_torque: float = field(default=0.15, metadata=above(0.0))
    tick_period: float = field(default=0.001, metadata=above(0.0))
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    pressure: PressureConfig = field(default_factory=PressureConfig)

    def __post_init__(self) -> None:
        check_bounds(self)
        if self.average_ticks >= self.pulse_ticks:
            raise ValueError(
                f"average_ticks ({self.average_ticks}) must be below pulse_ticks ({self.pulse_ticks})"
            )


@dataclass(frozen=True)
class Pulse:
    """One held code and what it gave.

    Attributes:
        code: D/A code held (codes).
        torque: Settled measured torque (N m), the lag's remainder corrected; nan when cut short.
        ticks: Ticks it was held (fewer than ``pulse_ticks`` when the window or speed cut it).
        displacement: Joint motion over the pulse (counts, raw direction).
        cut: Why it was cut short ("" when it was not).
        samples: Measured torque of each tick held (N m).
        held: Measured torque over the rest before it (N m): the load the trapped oil carried (gravity).
    """

    code: int
    torque: float
    ticks: int
    displacement: int
    cut: str
    samples: tuple[float, ...]
    held: float

    @property
    def opened(self) -> float:
        """How far the settled torque moved from the held one (N m): the valve's answer, not the load's."""
        return abs(self.torque - self.held) if math.isfinite(self.torque) else math.nan


@dataclass(frozen=True)
class JointJog:
    """One joint's valve and encoder as ``jog`` found them.

    Attributes:
        joint: 0 (alpha) or 1 (beta).
        direction: +1 if the counter counts up as q grows, -1 if down.
        polarity: +1 if a positive code drives q positive, -1 if negative.
        null_bias: Code at which the spool is at null (codes).
        deadband: Overlap, half the distance between the two onsets (codes).
        gain_positive: Codes per N m of a torque driving q positive (``bridge.valve.gain``).
        gain_negative: Codes per N m of a torque driving q negative (``bridge.valve.gain_negative``).
        onsets: Codes where each side starts to give torque (low side, high side).
        lag: Time constant of the torque's rise (s).
        excursion: Largest |q - q_start| during the jog (rad).
        pulses: Every pulse, in order.
    """

    joint: int
    direction: int
    polarity: int
    null_bias: float
    deadband: float
    gain_positive: float
    gain_negative: float
    onsets: tuple[float, float]
    lag: float
    excursion: float
    pulses: tuple[Pulse, ...]


class PulseRun:
    """The pulses of one joint's jog, with the safety checks of every tick."""

    def __init__(
        self, host: BenchHost, config: JogConfig, joint: int, held: tuple[int, int], origin: tuple[int, int]
    ) -> None:
        self.host, self.config, self.joint = host, config, joint
        self.held = held
        self.held_known = True
        """The other valve's held code is its null: False stops the jog once the other joint drifts."""
        self.start = origin
        self.quantum = [float(q) for q in config.encoder.quantum]
        self.bits = config.encoder.counter_bits
        self.excursion = 0.0
        self.direction: int | None = None
        self.load = self.rest()

    def rest(self) -> float:
        """Valves disabled for ``rest_ticks``; the measured torque over the last 20 of them (N m)."""
        frames = self.host.hold(self.config.rest_ticks)
        return float(np.mean([self.torque(frame.adc) for frame in frames[-20:]]))

    def offset(self, counts: tuple[int, int], j: int) -> int:
        """Joint ``j``'s raw counts relative to the start (counts, wrap-aware)."""
        return int(signed_counts(np.array([counts[j]]), self.start[j], self.bits)[0])

    def torque(self, adc: tuple[int, int, int, int]) -> float:
        """The jogged joint's measured torque of one feedback's A/D codes (N m)."""
        pressure = self.config.pressure
        j = self.joint
        return (adc[1 + j] - pressure.zero_code[j]) * pressure.torque_per_code[j]

    def check(self, status: int, faults: int) -> None:
        """Stops on a board fault or a latched e-stop."""
        if faults or status & StatusBit.ESTOP_LATCHED:
            raise MotionStopError(
                f"jog of {JOINTS[self.joint]} stopped: the board reported faults {faults:#06x} / status "
                f"{status:#06x}; run probe again once it is cleared"
            )

    def pulse(self, code: int) -> Pulse:
        """Holds ``code`` on the joint (the other at its held code), cut at the window or the speed limit."""
        config, j = self.config, self.joint
        codes = (code, self.held[1]) if j == 0 else (self.held[0], code)
        frame = self.host.feedback
        assert frame is not None
        begin = self.offset(frame.counts, j)
        history = [frame.counts]
        samples: list[float] = []
        cut = ""
        speed_ticks = 10
        for tick in range(config.pulse_ticks):
            frame = self.host.answer(codes)
            self.check(frame.status, frame.faults)
            samples.append(self.torque(frame.adc))
            history.append(frame.counts)
            for k in range(2):
                where = abs(self.offset(frame.counts, k))
                moved = where * self.quantum[k]
                self.excursion = max(self.excursion, moved) if k == j else self.excursion
                if k != j and not self.held_known and moved > _HELD_DRIFT * config.window:
                    self.host.hold(config.rest_ticks)
                    raise _HeldJointOpenError(
                        f"jog of {JOINTS[j]} stopped: {JOINTS[k]} drifted {moved:.3f} rad at code 0: "
                        f"{JOINTS[k]}'s null bias is past its overlap"
                    )
                outward = len(history) > 10 and where - abs(self.offset(history[-11], k)) > _OUTWARD
                if moved > config.window and outward:
                    cut = f"{JOINTS[k]} at the window's edge ({moved:.3f} rad)"
                    if moved > 1.5 * config.window:
                        self.host.hold(config.rest_ticks)
                        raise MotionStopError(
                            f"jog of {JOINTS[j]} stopped: {JOINTS[k]} moved {moved:.3f} rad from its start, "
                            f"past 1.5x the window of {config.window:g} rad: the valves do not stop it; "
                            "check the valve's fail-safe position"
                        )
            if not cut and len(history) > speed_ticks:
                for k in range(2):
                    then = self.offset(history[-1 - speed_ticks], k)
                    speed = abs(self.offset(frame.counts, k) - then) * self.quantum[k]
                    speed /= speed_ticks * config.tick_period
                    if speed > config.velocity_limit:
                        cut = f"{JOINTS[k]} at {speed:.2f} rad/s, past the limit of {config.velocity_limit:g}"
            displacement = self.offset(frame.counts, j) - begin
            if (
                tick >= config.pulse_ticks // 2
                and abs(float(np.mean(samples[-10:]))) > config.counting_torque
                and abs(displacement) < _MIN_DISPLACEMENT
            ):
                self.host.hold(config.rest_ticks)
                raise MotionStopError(
                    f"jog of {JOINTS[j]} stopped: its valve gives {float(np.mean(samples[-10:])):.2f} N m "
                    "but "
                    f"its encoder moved {displacement} counts: the encoder does not count (check its cable), "
                    "or the joint is blocked"
                )
            if cut:
                break
        load, self.load = self.load, self.rest()
        ticks = len(samples)
        torque = float("nan") if cut else float(np.mean(samples[-config.average_ticks :]))
        return Pulse(code, torque, ticks, displacement, cut, tuple(samples), load)


_LAGS = np.geomspace(0.001, 0.2, 80)
"""Time constants (s) the lag's fit tries."""


def _lag_basis(lag: float, ticks: int, period: float) -> np.ndarray:
    """Weight of the starting torque in the mean over each tick of a first-order rise, shape (ticks,)."""
    k = np.arange(ticks, dtype=np.float64)
    return np.asarray(
        lag / period * (np.exp(-k * period / lag) - np.exp(-(k + 1.0) * period / lag)), dtype=np.float64
    )


def _settle(pulses: list[Pulse], config: JogConfig) -> tuple[list[Pulse], float]:
    """The pulses with their settled torque from a first-order rise fitted to every tick, and its lag (s).

    Per pulse the torque over tick k is ``A (1 - m_k) + s0 m_k`` (``m_k``: the start's weight in the
    tick's mean); one time constant for all pulses, the one of least squared residual.
    """
    used = [p for p in pulses if not p.cut and p.opened > config.open_torque]
    if not used:
        return pulses, 0.0
    best, best_cost = 0.0, math.inf
    for lag in _LAGS:
        weight = _lag_basis(float(lag), config.pulse_ticks, config.tick_period)
        design = np.stack([1.0 - weight, weight], axis=1)
        cost = 0.0
        for pulse in used:
            samples = np.asarray(pulse.samples)
            solution = np.linalg.lstsq(design, samples, rcond=None)
            cost += float(np.sum((design @ solution[0] - samples) ** 2))
        if cost < best_cost:
            best, best_cost = float(lag), cost
    weight = _lag_basis(best, config.pulse_ticks, config.tick_period)
    design = np.stack([1.0 - weight, weight], axis=1)
    out = []
    for pulse in pulses:
        torque = pulse.torque
        if not pulse.cut:
            torque = float(np.linalg.lstsq(design, np.asarray(pulse.samples), rcond=None)[0][0])
        out.append(dataclasses.replace(pulse, torque=torque))
    return out, best


def _fit(points: list[Pulse]) -> tuple[float, float]:
    """(torque per code, onset code) of a line through the side's settled torques."""
    codes = np.array([p.code for p in points], dtype=np.float64)
    torques = np.array([p.torque for p in points], dtype=np.float64)
    slope, intercept = np.polyfit(codes, torques, 1)
    return float(slope), float(-intercept / slope)


def jog_joint(
    host: BenchHost,
    config: JogConfig,
    joint: int,
    held: tuple[int, int],
    origin: tuple[int, int],
    *,
    held_known: bool = True,
) -> JointJog:
    """Jogs ``joint`` with the other valve at its code of ``held``; its truths from the pulses.

    The window is around ``origin`` (raw counts where the jog started), for both joints. ``held_known``:
    the other valve's held code is its null (it was jogged), else the jog stops once the other joint drifts
    past half the window.

    Raises:
        MotionStopError: A safety limit, a fault, no torque up to ``search_max``, or an encoder not counting.
        LinkLostError: The link failed.
    """
    run = PulseRun(host, config, joint, held, origin)
    run.held_known = held_known
    name = JOINTS[joint]
    pulses: list[Pulse] = []
    onset: dict[int, int] = {}  # side (+1 / -1) -> first code that answered
    search = {1: config.search_step, -1: config.search_step}
    stairs: dict[int, list[int]] = {1: [], -1: []}
    side = 1
    sign_of: dict[int, int] = {}  # side -> sign of its torque
    while True:
        todo = [s for s in (1, -1) if s not in onset]  # search both sides first: only one may push out
        todo = todo or [s for s in (1, -1) if stairs[s]]
        if not todo:
            break
        if len(todo) == 2 and run.direction is not None and sign_of:
            # go back towards the start: the side whose torque drives the joint back, if known
            where = run.offset(host.feedback.counts, joint) * run.direction if host.feedback else 0
            wanted = -1 if where > 0 else 1
            known = [s for s in todo if s in sign_of and sign_of[s] == wanted]
            side = known[0] if known else side
        elif len(todo) == 1:
            side = todo[0]
        if side not in onset:
            code = side * search[side]
            if search[side] > config.search_max:
                raise MotionStopError(
                    f"jog of {name} stopped: its valve gave no torque up to {side * config.search_max:+d} "
                    "codes: "
                    "check the valve's cable and driver, the supply, and the load-pressure transducer"
                )
            search[side] += config.search_step
        else:
            code = stairs[side].pop(0)
        pulse = run.pulse(code)
        pulses.append(pulse)
        answer = pulse.torque - pulse.held
        if not math.isfinite(answer) and pulse.ticks >= 20:
            answer = float(np.mean(pulse.samples[-10:])) - pulse.held  # cut short: did it open?
        if side not in onset and abs(answer) > config.open_torque:
            onset[side] = code
            sign_of[side] = int(np.sign(answer))
            levels = range(1 if not pulse.cut else 0, config.stair_levels + 1)  # cut: that code again
            stairs[side] = [code + side * config.stair_step * k for k in levels]
        if pulse.opened > config.open_torque:
            if abs(pulse.displacement) >= _MIN_DISPLACEMENT and abs(pulse.torque) > config.counting_torque:
                vote = int(np.sign(pulse.displacement) * np.sign(pulse.torque))
                if run.direction is not None and vote != run.direction:
                    raise MotionStopError(
                        f"jog of {name} stopped: the joint moved against the measured torque on one pulse "
                        "and with it on another: check the load-pressure transducers and for a blocked joint"
                    )
                run.direction = vote
        elif pulse.cut and side in onset:
            stairs[side] = []  # the joint runs too fast at this level: nothing higher on this side
        side = -side
    if run.direction is None and any(p.cut for p in pulses):
        raise MotionStopError(
            f"jog of {name} stopped: every pulse that moved the joint was cut at the window or the speed "
            "limit, too few settled pulses: widen --window"
        )
    if run.direction is None:
        raise MotionStopError(
            f"jog of {name} stopped: no pulse moved the joint by {_MIN_DISPLACEMENT} counts: its "
            "encoder does not count, or the joint is blocked"
        )
    settled, lag = _settle(pulses, config)
    fits: dict[int, tuple[float, float]] = {}
    for s in (1, -1):
        points = [
            p
            for p in settled
            if math.isfinite(p.torque)
            and np.sign(p.code) == s
            and abs(p.code) >= abs(onset[s])
            and p.opened > config.open_torque
            and np.sign(p.torque) == sign_of[s]
        ]
        if len(points) < 2:
            raise MotionStopError(
                f"jog of {name} stopped: only {len(points)} settled pulse(s) on the "
                f"{'+' if s > 0 else '-'} side, too few settled pulses: widen --window"
            )
        fits[s] = _fit(points)
    if sign_of[1] == sign_of[-1]:
        raise MotionStopError(
            f"jog of {name} stopped: both sides of the valve give torque of the same sign: check the "
            "load-pressure transducer and the valve's wiring"
        )
    polarity = sign_of[1]
    low, high = fits[-1][1], fits[1][1]
    slope_positive = fits[1][0] if polarity > 0 else fits[-1][0]
    slope_negative = fits[-1][0] if polarity > 0 else fits[1][0]
    return JointJog(
        joint=joint,
        direction=run.direction,
        polarity=polarity,
        null_bias=(low + high) / 2.0,
        deadband=max((high - low) / 2.0, 0.0),
        gain_positive=1.0 / abs(slope_positive),
        gain_negative=1.0 / abs(slope_negative),
        onsets=(low, high),
        lag=lag,
        excursion=run.excursion,
        pulses=tuple(settled),
    )


def run_jog(host: BenchHost, config: JogConfig, joints: tuple[int, ...] = (0, 1)) -> tuple[JointJog, ...]:
    """Jogs each of ``joints`` in turn; a joint done holds its valve at its null bias for the next.

    A joint that drifts at code 0 while another is jogged (its null bias past its overlap) is jogged first,
    the other then held at its null. Results in the order of ``joints``.

    Raises:
        MotionStopError, LinkLostError: As :func:`jog_joint`.
    """
    held = [0, 0]
    found: dict[int, JointJog] = {}
    origin = (host.feedback if host.feedback is not None else host.next()).counts
    todo = list(joints)
    while todo:
        joint = todo[0]
        try:
            result = jog_joint(host, config, joint, (held[0], held[1]), origin, held_known=not todo[1:])
        except _HeldJointOpenError as error:
            other = 1 - joint
            if other not in todo[1:] or found or todo != list(joints):
                raise MotionStopError(
                    f"{error}, and its jog cannot come first: both valves open at code 0; re-zero the "
                    "valves' null on their drivers"
                ) from None
            todo = [other, joint]
            continue
        held[joint] = round(result.null_bias)
        found[joint] = result
        todo.pop(0)
    return tuple(found[joint] for joint in joints)
