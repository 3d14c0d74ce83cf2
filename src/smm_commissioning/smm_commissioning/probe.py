"""``probe``: the bench read with the output disabled, nothing moving; its faults named (pure, over a host).

Session and host lock, board faults, e-stop, supply, each encoder's counts and their noise, each load-pressure
channel; the raw counts at the pose the operator confirms (the joint zero); on CANopen the nodes, their
states and faults (:mod:`smm_commissioning.probe_canopen`). docs/COMMISSIONING.md, "probe".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from smm_hw_bridge.canopen_device import CanopenDevice
from smm_hw_bridge.device import Feedback
from smm_hw_bridge.encoder import EncoderConfig
from smm_hw_bridge.pressure import PressureConfig
from smm_hw_bridge.protocol import ADC_MAX, FaultBit, StatusBit
from smm_schema.ranges import above, at_least, bounds, check_bounds, no_range

from smm_commissioning.host import BenchHost
from smm_commissioning.probe_canopen import HeartbeatWatch, NodeReading, canopen_findings, pressure_actuals

__all__ = ["JOINTS", "ProbeConfig", "ProbeResult", "parse_pose", "run_probe", "signed_counts", "zero_offset"]

JOINTS = ("alpha", "beta")
_FAULT_WORDS = {
    FaultBit.SUPPLY_LOW: "the board reports SUPPLY_LOW and keeps the valves at null: start the pump, open "
    "the supply valve, check the supply transducer on A/D channel 0",
    FaultBit.VALVE_DRIVER: "the board reports VALVE_DRIVER: check the valve cables and the driver's fuse",
    FaultBit.ENCODER: "the board reports ENCODER: check the encoder cables and their supply",
    FaultBit.DAC: "the board reports DAC: the D/A converter failed its self-test; power-cycle the board",
    FaultBit.OVERTEMP: "the board reports OVERTEMP: let it cool, check its fan",
    FaultBit.INTERNAL: "the board reports INTERNAL: power-cycle it; if it stays, replace it",
}


@dataclass(frozen=True)
class ProbeConfig:
    """What ``probe`` reads and what it checks the readings against.

    Attributes:
        ticks: Feedbacks read with the output disabled (board ticks), in [100, 600000].
        supply_min: Lowest supply pressure the steps run at (bar), >= 0.
        supply_bar_per_code: Supply pressure per A/D code of channel 0 (bar), > 0
            (``bridge.supply_bar_per_code``).
        rest_torque_max: Largest |measured torque| at rest with the valves disabled (N m), > 0.
        rest_motion_max: Largest motion of a joint at rest with the valves disabled (rad), > 0.
        stuck_spread: A load channel whose standard deviation is below this (codes) while the supply
            channel's is above it is stuck, > 0.
        pose: The joint angles (alpha, beta) the operator confirms the bench is at (rad): the zero is taken
            from them.
        encoder: Counts per revolution and counter width (``bridge.encoder.*``).
        pressure: Calibration of the load-pressure channels (``bridge.pressure.*``).
    """

    ticks: int = field(default=2000, metadata=bounds(100, 600_000))
    supply_min: float = field(default=8.0, metadata=at_least(0.0))
    supply_bar_per_code: float = field(default=25.0 / 4095.0, metadata=above(0.0))
    rest_torque_max: float = field(default=1.0, metadata=above(0.0))
    rest_motion_max: float = field(default=0.01, metadata=above(0.0))
    stuck_spread: float = field(default=0.3, metadata=above(0.0))
    pose: tuple[float, float] = field(default=(0.0, 0.0), metadata=no_range())
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    pressure: PressureConfig = field(default_factory=PressureConfig)

    def __post_init__(self) -> None:
        check_bounds(self)
        if not isinstance(self.encoder, EncoderConfig) or not isinstance(self.pressure, PressureConfig):
            raise ValueError("encoder and pressure must be an EncoderConfig and a PressureConfig")


@dataclass(frozen=True)
class ProbeResult:
    """What ``probe`` read, and what is wrong with it.

    Attributes:
        ticks: Feedbacks read.
        supply_bar: Mean supply pressure (bar).
        counts_at_pose: Raw counter values at the confirmed pose (alpha, beta) (the last feedback's).
        counts_span: Largest minus smallest count at rest, per joint (counts, wrap-aware).
        counts_std: Standard deviation of the counts at rest, per joint (counts).
        rest_torque: Mean measured torque per joint at rest (N m).
        load_std: Standard deviation of the load-pressure codes per joint (codes).
        supply_std: Standard deviation of the supply code (codes).
        faults: Fault bits seen (OR over the run).
        status: Status bits of the last feedback.
        pose: The confirmed pose (rad).
        findings: One sentence per fault found; empty when the bench passed.
        notes: What could not be checked, and why.
        enabled: True if any enabled command was sent (never, by construction; reported as a check).
        link: ``frame`` or ``canopen``.
        nodes: Each CANopen node as read (none on the frame link).
    """

    ticks: int
    supply_bar: float
    counts_at_pose: tuple[int, int]
    counts_span: tuple[int, int]
    counts_std: tuple[float, float]
    rest_torque: tuple[float, float]
    load_std: tuple[float, float]
    supply_std: float
    faults: int
    status: int
    pose: tuple[float, float]
    findings: tuple[str, ...]
    notes: tuple[str, ...]
    enabled: bool
    link: str = "frame"
    nodes: tuple[NodeReading, ...] = ()

    @property
    def passed(self) -> bool:
        """No finding."""
        return not self.findings


def signed_counts(raw: np.ndarray, reference: int, bits: int) -> np.ndarray:
    """Raw counter values relative to ``reference``, unwrapped modulo 2**bits (counts), int64."""
    modulus = 1 << bits
    half = modulus >> 1
    return ((raw.astype(np.int64) - int(reference) + half) % modulus) - half


def run_probe(host: BenchHost, config: ProbeConfig) -> ProbeResult:
    """Reads the bench for ``config.ticks`` feedbacks with the output disabled and checks what it read.

    On the CANopen link the bus's own checks too (:func:`~smm_commissioning.probe_canopen.canopen_findings`).

    Raises:
        LinkLostError: No feedback, or the board restarted.
    """
    master = host.device if isinstance(host.device, CanopenDevice) else None
    watch = HeartbeatWatch(master) if master is not None else None
    first = host.next()
    findings: list[str] = []
    notes: list[str] = []
    if first.host_session not in (0, host.session):
        findings.append(
            f"another host holds the board (host session {first.host_session:#010x}): stop the bridge or "
            "the other tool that drives it, then probe again"
        )
    frames: list[Feedback] = []
    pressures: list[tuple[int, ...]] = []
    for _ in range(config.ticks):
        frames.append(host.answer(None))
        if master is not None:
            pressures.append(pressure_actuals(master))
    counts = np.array([frame.counts for frame in frames], dtype=np.int64)
    adc = np.array([frame.adc for frame in frames], dtype=np.int64)
    faults = 0
    for frame in frames:
        faults |= frame.faults
    status = frames[-1].status
    nodes: tuple[NodeReading, ...] = ()
    if master is None:
        findings += _fault_words(faults)
    if any(frame.status & StatusBit.ESTOP_LATCHED for frame in frames):
        findings.append("the e-stop is latched: release it and re-arm the board before the next step")
    supply_codes = adc[:, 0].astype(np.float64)
    supply = float(np.mean(supply_codes)) * config.supply_bar_per_code
    supply_std = float(np.std(supply_codes))
    if master is None:
        if supply < config.supply_min:
            findings.append(
                f"supply pressure {supply:.2f} bar, below the {config.supply_min:g} bar the steps need: "
                "start the pump, open the supply valve, check the supply transducer on A/D channel 0"
            )
    elif watch is not None:
        watch.await_all(host)
        supply, supply_std = master.config.supply_bar, 0.0
        found, more, nodes = canopen_findings(
            master, watch, np.array(pressures, dtype=np.int64).reshape(-1, 2), config.supply_min
        )
        findings += found
        notes += more

    bits = config.encoder.counter_bits
    relative = np.stack([signed_counts(counts[:, j], int(counts[0, j]), bits) for j in range(2)], axis=1)
    span = tuple(int(np.ptp(relative[:, j])) for j in range(2))
    counts_std = tuple(float(np.std(relative[:, j])) for j in range(2))
    quantum = config.encoder.quantum
    for j, name in enumerate(JOINTS):
        other = 1 - j
        where = "the counter input on the board" if master is None else f"{_encoder_name(master, j)}'s node"
        if span[j] == 0 and span[other] > 0:
            findings.append(
                f"encoder {name} does not count: its counter stayed at {int(counts[0, j])} for {len(frames)} "
                f"ticks while {JOINTS[other]}'s moved over {span[other]} counts; check its cable, its supply "
                f"and {where}"
            )
        moved = span[j] * float(quantum[j])
        if moved > config.rest_motion_max:
            findings.append(
                f"joint {name} moved {moved:.4f} rad with the valves disabled (at most "
                f"{config.rest_motion_max:g}): the valves do not hold it, or its encoder jumps; check the "
                "valve's fail-safe position and the encoder's shielding"
            )
    if span == (0, 0):
        notes.append(
            "neither encoder moved by a count at rest: whether they count is checked by jog's first motion"
        )

    rest_torque: list[float] = []
    load_std: list[float] = []
    for j, name in enumerate(JOINTS):
        channel = adc[:, 1 + j]
        spread = float(np.std(channel.astype(np.float64)))
        load_std.append(spread)
        torque = (float(np.mean(channel)) - config.pressure.zero_code[j]) * config.pressure.torque_per_code[j]
        rest_torque.append(torque)
        problem = None if master is not None else _channel_problem(channel, j, spread, supply_std, config)
        if problem is not None:  # on CANopen the A/D carries 0x6381:01, checked as the valves sent it
            findings.append(problem)
            continue
        if abs(torque) > config.rest_torque_max:
            findings.append(
                f"load pressure of {name} reads {torque:.2f} N m with the valves disabled and nothing moving "
                f"(at most {config.rest_torque_max:g}): check the transducer's zero "
                "(bridge.pressure.zero_code)"
            )
    if master is None and supply_std < config.stuck_spread:
        notes.append("the A/D shows no noise: a stuck load-pressure channel cannot be told from a quiet one")
    last = frames[-1].counts
    return ProbeResult(
        ticks=len(frames),
        supply_bar=supply,
        counts_at_pose=(int(last[0]), int(last[1])),
        counts_span=(span[0], span[1]),
        counts_std=(counts_std[0], counts_std[1]),
        rest_torque=(rest_torque[0], rest_torque[1]),
        load_std=(load_std[0], load_std[1]),
        supply_std=supply_std,
        faults=faults,
        status=status,
        pose=config.pose,
        findings=tuple(findings),
        notes=tuple(notes),
        enabled=host.enabled_ever,
        link="frame" if master is None else "canopen",
        nodes=nodes,
    )


def _fault_words(faults: int) -> list[str]:
    """The frame board's fault bits in words."""
    findings = [words for bit, words in _FAULT_WORDS.items() if faults & bit]
    unknown = faults & ~sum(int(bit) for bit in _FAULT_WORDS)
    if unknown:
        findings.append(
            f"the board reports fault bits {unknown:#06x} this tool does not know: see its manual"
        )
    return findings


def _channel_problem(
    channel: np.ndarray, j: int, spread: float, supply_std: float, config: ProbeConfig
) -> str | None:
    """A frame board's load-pressure A/D channel at its rail, or stuck while the supply channel varies."""
    name = JOINTS[j]
    if int(channel.min()) <= 0 or int(channel.max()) >= ADC_MAX:
        return (
            f"load-pressure channel {1 + j} ({name}) reads its rail "
            f"({int(channel.min())}..{int(channel.max())}): the transducer is unplugged or shorted; "
            "check its cable and supply"
        )
    if spread < config.stuck_spread <= supply_std:
        return (
            f"load-pressure channel {1 + j} ({name}) is stuck at {int(channel[0])} (no noise over "
            f"{len(channel)} ticks while the supply channel varies by {supply_std:.2f} codes): check the "
            "transducer and its A/D input"
        )
    return None


def _encoder_name(master: CanopenDevice, joint: int) -> str:
    return next(node.name for node in master.nodes if node.kind == "encoder" and node.joint == joint)


def zero_offset(counts: int, pose: float, direction: int, encoder: EncoderConfig, joint: int) -> int:
    """Raw counter value at q = 0 given ``counts`` at ``pose`` (rad) and the counting ``direction``."""
    steps = round(pose / float(encoder.quantum[joint]))
    return (counts - direction * steps) % encoder.modulus


def parse_pose(text: str) -> tuple[float, float]:
    """``home`` -> (0, 0); ``A,B`` -> (A, B) rad, finite.

    Raises:
        ValueError: Not ``home`` nor two finite numbers.
    """
    if text.strip() == "home":
        return (0.0, 0.0)
    parts = text.split(",")
    if len(parts) != 2:
        raise ValueError(f"--pose takes 'home' or 'ALPHA,BETA' in rad, got {text!r}")
    values = tuple(float(part) for part in parts)
    if not all(math.isfinite(value) for value in values):
        raise ValueError(f"--pose must be finite, got {text!r}")
    return values[0], values[1]
