"""``identify``: the excitation on jog's parameters, the model and the valves' gains; the overlap's edges.

The excitation is closed through the bridge on the jog's parameters, its bag fitted on the measured torque
(the valve's gain per direction with it), and each edge of each overlap found again to a code from the
joint's motion under codes around it.

docs/COMMISSIONING.md, "identify".
"""

from __future__ import annotations

import io
import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from smm_analysis.closed_loop import Trajectory
from smm_analysis.errors import IdentificationError
from smm_analysis.identification import EstimationSettings, FilterSettings, Identification
from smm_analysis.identification.estimate import estimate
from smm_analysis.identification.streaming import StreamedRun, read_run
from smm_analysis.identification.valve_gain import ValveGain, estimate_gain
from smm_analysis.runs.commands import streams_of
from smm_analysis.runs.from_trajectory import write_trajectory_bag
from smm_analysis.runs.window import TimeWindow
from smm_controller.chain import make_chain
from smm_controller.excitation import ExcitationReference
from smm_hw_bridge.bridge_config import BridgeConfig
from smm_schema.ranges import above, at_least, bounds, check_bounds

from smm_commissioning.closed import LoopRecord, run_loop
from smm_commissioning.errors import CommissioningError, MotionStopError
from smm_commissioning.host import BenchHost
from smm_commissioning.jog import JogConfig, PulseRun
from smm_commissioning.probe import JOINTS, signed_counts
from smm_dynamics import SMMParameters, gravity_vector, mass_matrix

__all__ = [
    "LOOP_BLEND",
    "OPEN_MARGIN",
    "Edge",
    "IdentifyConfig",
    "IdentifyResult",
    "excite",
    "find_edges",
    "fit_bag",
    "pulse_torque",
]

FloatArray = NDArray[np.float64]
_MOVED = 5
"""Counts the mean of a pulse's last 30 positions must lie from the mean of its first 30 for the pulse to
have moved its joint: six standard deviations of the encoder's rest noise (3 counts) in that difference."""
_ENDS = 30
LOOP_BLEND = 0.01
"""``bridge.valve.deadband_blend`` once the edges are known to a code (codes): a demand's code jumps over the
overlap, so the spool is not held inside it while the torque passes through zero at speed (docs/
COMMISSIONING.md, "Why the null bias, and how fine")."""
OPEN_MARGIN = 2.0
"""Codes ``bridge.valve.deadband`` puts past each edge found, so that an edge found a code or so short still
opens the valve for a demand near zero (same section)."""


@dataclass(frozen=True)
class IdentifyConfig:
    """How ``identify`` excites the bench, fits the model and finds the overlap's edges.

    Attributes:
        excitation: The ``excite`` reference (docs/IDENTIFICATION.md): limits within the soft limits.
        bootstrap: Bootstrap replicates of the intervals, in [20, 10000].
        max_error: Largest tracking error of the excitation (rad), > 0: past it the loop stops.
        edge_span: Codes inside the jog's edge where the search of an edge starts, in [10, 1000].
        edge_step: Code step of the search outwards, in [1, 100].
        edge_open: Pulses past the edge that move the joint, per edge, in [2, 20].
        edge_ticks: Ticks one code of the search is held, in [150, 2000].
        settle_ticks: First ticks of a pulse left out of its torque (the valve's lag), in [10, 1000].
        velocity_ticks: Half window of the velocity fits (ticks), in [5, 100].
        window: Largest excursion of the search from its start (rad), in (0, 0.5].
        velocity_limit: Largest speed of the search (rad/s), > 0.
    """

    excitation: ExcitationReference = field(default_factory=ExcitationReference)
    bootstrap: int = field(default=100, metadata=bounds(20, 10_000))
    max_error: float = field(default=0.3, metadata=above(0.0))
    edge_span: int = field(default=60, metadata=bounds(10, 1000))
    edge_step: int = field(default=8, metadata=bounds(1, 100))
    edge_open: int = field(default=3, metadata=bounds(2, 20))
    edge_ticks: int = field(default=350, metadata=bounds(150, 2000))
    settle_ticks: int = field(default=120, metadata=bounds(10, 1000))
    velocity_ticks: int = field(default=25, metadata=bounds(5, 100))
    window: float = field(default=0.2, metadata=bounds(0.0, 0.5, low_open=True))
    velocity_limit: float = field(default=1.5, metadata=at_least(1e-3))

    def __post_init__(self) -> None:
        check_bounds(self)
        if self.settle_ticks + 4 * self.velocity_ticks >= self.edge_ticks:
            raise ValueError(
                f"edge_ticks ({self.edge_ticks}) must exceed settle_ticks + 4 velocity_ticks "
                f"({self.settle_ticks + 4 * self.velocity_ticks})"
            )


@dataclass(frozen=True)
class Edge:
    """One edge of a valve's overlap, found from the joint's motion under codes around it.

    Attributes:
        joint: 0 (alpha) or 1 (beta).
        side: +1 (the edge above the null) or -1.
        start: The jog's edge (codes).
        edge: Between the last code that left the joint held and the first that moved it (codes).
        line: Where the line through the torques of the codes that moved the joint crosses zero (codes): the
            edge again, through the model's friction and offset (a check).
        slope: Torque per code past the edge (N m per code).
        residual: RMS of the open pulses' torques about the fitted line (N m).
        codes: The codes held (codes).
        torques: The mean torque each gave after its settling, from the motion and the model (N m).
        moved: Whether each moved the joint (the valve opened; the line is fitted through those).
    """

    joint: int
    side: int
    start: float
    edge: float
    line: float
    slope: float
    residual: float
    codes: tuple[int, ...]
    torques: tuple[float, ...]
    moved: tuple[bool, ...]


@dataclass(frozen=True)
class IdentifyResult:
    """What ``identify`` found.

    Attributes:
        identification: The model and its intervals (smm-bag identify on the run's bag).
        gain: The valve's measured over modelled torque per joint and direction (a check: not applied).
        edges: Both edges of both valves (alpha low, alpha high, beta low, beta high).
        record: The excitation run.
        warnings: What the identification left out, one line each.
    """

    identification: Identification
    gain: ValveGain
    edges: tuple[Edge, ...]
    record: LoopRecord
    warnings: tuple[str, ...]

    def valve(self) -> dict[str, list[float] | float]:
        """``bridge.valve.null_bias`` and ``deadband`` (+ the margin) of the edges, ``deadband_blend``."""
        edges = {(e.joint, e.side): e.edge for e in self.edges}
        half = [(edges[j, 1] - edges[j, -1]) / 2.0 for j in range(2)]
        return {
            "bridge.valve.null_bias": [round((edges[j, 1] + edges[j, -1]) / 2.0, 2) for j in range(2)],
            "bridge.valve.deadband": [round(half[j] + OPEN_MARGIN, 2) for j in range(2)],
            "bridge.valve.deadband_blend": LOOP_BLEND,
        }


def excite(host: BenchHost, bridge: BridgeConfig, config: IdentifyConfig) -> LoopRecord:
    """The excitation, FPDESO on the nominal model, closed on ``bridge``'s parameters; then 0.5 s at rest.

    Raises:
        MotionStopError, LinkLostError: As :func:`~smm_commissioning.closed.run_loop`.
    """
    reference = config.excitation
    chain = make_chain("fpdeso", SMMParameters())
    return run_loop(host, bridge, chain, reference, reference.duration + 0.5, max_error=config.max_error)


def write_bag(record: LoopRecord, path: Path) -> Path:
    """The run as ``smm-bag`` reads a bench's run: joint_states with the effort, the measured torque."""
    n = len(record.t_ns)
    applied = np.vstack([record.effort[1:], record.effort[-1:]])  # the torque over [t_k, t_k+1]
    zeros = np.zeros((n, 2))
    trajectory = Trajectory(
        scenario="excite",
        controller="fpdeso",
        seed=0,
        control_period=float(record.t_ns[1] - record.t_ns[0]) * 1e-9,
        model_params=SMMParameters(),
        plant_params=SMMParameters(),
        t_ns=record.t_ns,
        reference=record.reference,
        measured_position=record.position,
        position=record.position,
        velocity=zeros,
        command_torque=record.command,
        applied_torque=applied,
        disturbance_estimate=zeros,
        disturbance_torque=zeros,
    )
    write_trajectory_bag(trajectory, path, internals=False, measured_torque=record.measured, plant="hardware")
    return path


def fit_bag(bag: Path, bootstrap: int) -> tuple[Identification, ValveGain, StreamedRun]:
    """``smm-bag identify BAG`` with the measured torque: the model, its intervals, the valve's gain.

    Raises:
        CommissioningError: The run cannot give a sound model or the valve's gain (and why).
    """
    settings = EstimationSettings(bootstrap=bootstrap)
    with tempfile.TemporaryDirectory(prefix="smm-commission-") as directory:
        try:
            (stream, _), *_ = streams_of(
                bag, window=TimeWindow(), segments=False, quiet=True, err=io.StringIO()
            )
            run = read_run(
                str(bag.name),
                stream,
                Path(directory) / "run.spool",
                FilterSettings(),
                gravity=SMMParameters().gravity,
                gravity_sign=SMMParameters().gravity_sign,
                block=settings.block,
            )
            result = estimate([run.sums], SMMParameters(), settings)
            if run.gain is None:
                raise CommissioningError("the run has no measured torque at every step: no valve gain")
            gain = estimate_gain([run.gain], settings.bootstrap, settings.seed)
        except IdentificationError as error:
            raise CommissioningError(f"the excitation run gives no sound model: {error}") from error
    return result, gain, run


def pulse_torque(
    q: FloatArray, joint: int, model: SMMParameters, *, period: float, settle: int, half: int
) -> float:
    """Mean torque on ``joint`` after ``settle`` ticks of a pulse, from its motion q (n, 2) (rad) (N m).

    M dq'/dt + F(q') + G(q) of the ``model`` integrated between two velocity fits of ``half`` ticks each
    side; ``period`` the tick (s).
    """
    n = len(q)
    t1, t2 = settle + half, n - 1 - half
    times = np.arange(-half, half + 1) * period

    def velocity(center: int) -> float:
        return float(np.polyfit(times, q[center - half : center + half + 1, joint], 1)[0])

    middle = q[(t1 + t2) // 2]
    inertia = float(mass_matrix(middle, model)[joint, joint])
    moved = float(q[t2, joint] - q[t1, joint])
    duration = (t2 - t1) * period
    gravity = float(np.sum(gravity_vector(q[t1:t2], model)[:, joint])) * period
    friction = model.viscous_friction[joint] * moved + model.torque_offset[joint] * duration
    if abs(moved) > 1e-4:
        friction += model.coulomb_friction[joint] * math.copysign(duration, moved)
    return (inertia * (velocity(t2) - velocity(t1)) + friction + gravity) / duration


def _line(codes: FloatArray, torques: FloatArray) -> tuple[float, float, float]:
    """(code of zero torque, torque per code, residual RMS) of a line through the open pulses."""
    slope, intercept = np.polyfit(codes, torques, 1)
    residual = torques - (slope * codes + intercept)
    return float(-intercept / slope), float(slope), float(np.sqrt(np.mean(residual**2)))


def find_edges(
    host: BenchHost, bridge: BridgeConfig, model: SMMParameters, config: IdentifyConfig
) -> tuple[Edge, ...]:
    """Both edges of both valves, a line fitted per edge to the torque of the codes past it.

    The torque of each code is that of the motion it gave (the model's M, F and G, :func:`pulse_torque`).

    Codes are stepped outwards from inside each of the jog's edges until ``edge_open`` of them moved the
    joint; the line through their torques crosses zero at the edge (a held joint's torque is the oil's,
    not the valve's: those are left out). The joint not searched is held at its null bias (locked in its
    overlap); the sides alternate so that the joint comes back.

    Raises:
        MotionStopError: The window or the speed limit cut a pulse, a fault, or no edge within reach.
    """
    jog = JogConfig(
        window=config.window,
        velocity_limit=config.velocity_limit,
        pulse_ticks=config.edge_ticks,
        average_ticks=config.edge_ticks // 2,
        encoder=bridge.encoder,
    )
    valve = bridge.valve
    held = (round(valve.null_bias[0]), round(valve.null_bias[1]))
    origin = (host.feedback if host.feedback is not None else host.next()).counts
    found = []
    for joint in (0, 1):
        run = PulseRun(host, jog, joint, held, origin)
        starts = {s: valve.null_bias[joint] + s * valve.deadband[joint] for s in (1, -1)}
        codes: dict[int, list[int]] = {1: [], -1: []}
        torques: dict[int, list[float]] = {1: [], -1: []}
        moved: dict[int, list[bool]] = {1: [], -1: []}
        step = 0
        while min(sum(m) for m in moved.values()) < config.edge_open:
            for side in (1, -1):
                if sum(moved[side]) >= config.edge_open:
                    continue
                code = round(starts[side] - side * config.edge_span + side * step * config.edge_step)
                if abs(code - starts[side]) > 4 * config.edge_span + 10 * config.edge_step:
                    raise MotionStopError(
                        f"identify stopped: {JOINTS[joint]}'s valve gave no motion up to code {code:+d}: "
                        "its overlap is not where jog found it; run jog again"
                    )
                torque, opened = _pulse(run, code, bridge=bridge, model=model, config=config)
                codes[side].append(code)
                torques[side].append(torque)
                moved[side].append(opened)
            step += 1
        for side in (-1, 1):
            held_code, moved_code = _bisect(
                run,
                side,
                codes=codes,
                torques=torques,
                moved=moved,
                bridge=bridge,
                model=model,
                config=config,
            )
            use = np.array(moved[side])
            line, slope, residual = _line(
                np.array(codes[side], dtype=np.float64)[use], np.array(torques[side])[use]
            )
            found.append(
                Edge(
                    joint,
                    side,
                    starts[side],
                    (held_code + moved_code) / 2.0,
                    line,
                    slope,
                    residual,
                    tuple(codes[side]),
                    tuple(torques[side]),
                    tuple(moved[side]),
                )
            )
        if joint == 0:  # alpha at its refined null while beta is searched
            held = (round((found[-1].edge + found[-2].edge) / 2.0), held[1])
    return tuple(found)


def _bisect(
    run: PulseRun,
    side: int,
    *,
    codes: dict[int, list[int]],
    torques: dict[int, list[float]],
    moved: dict[int, list[bool]],
    bridge: BridgeConfig,
    model: SMMParameters,
    config: IdentifyConfig,
) -> tuple[int, int]:
    """The adjacent codes (held, moved) around one edge: the scan's bracket halved (the pulses appended).

    Past the edge the spool leaves the overlap and the oil no longer holds the joint: a fraction of a code
    moves it by tens of counts, whatever the model's friction.

    Raises:
        MotionStopError: The scan's first code already moved the joint (jog's edge is far off).
    """
    first = moved[side].index(True)
    if first == 0:
        raise MotionStopError(
            f"identify stopped: {JOINTS[run.joint]}'s valve moved the joint at {codes[side][0]:+d}, "
            f"{config.edge_span} codes inside jog's edge: run jog again"
        )
    held_code, moved_code = codes[side][first - 1], codes[side][first]
    while abs(moved_code - held_code) > 1:
        middle = (held_code + moved_code) // 2
        torque, opened = _pulse(run, middle, bridge=bridge, model=model, config=config)
        codes[side].append(middle)
        torques[side].append(torque)
        moved[side].append(opened)
        held_code, moved_code = (held_code, middle) if opened else (middle, moved_code)
    return held_code, moved_code


def _pulse(
    run: PulseRun,
    code: int,
    *,
    bridge: BridgeConfig,
    model: SMMParameters,
    config: IdentifyConfig,
) -> tuple[float, bool]:
    """Holds ``code``; its mean torque after the settling (N m) and whether it moved the joint."""
    host, joint = run.host, run.joint
    first = len(host.rows)
    pulse = run.pulse(code)
    if pulse.cut:
        raise MotionStopError(
            f"identify stopped: a pulse of {JOINTS[joint]} at {code:+d} was cut ({pulse.cut})"
        )
    counts = host.record()[first : first + pulse.ticks + 1, 1:3]
    encoder = bridge.encoder
    q = np.stack(
        [
            encoder.direction[j]
            * signed_counts(counts[:, j], encoder.zero_offset[j], encoder.counter_bits).astype(np.float64)
            * float(encoder.quantum[j])
            for j in range(2)
        ],
        axis=1,
    )
    torque = pulse_torque(
        q,
        joint,
        model,
        period=bridge.period_ns * 1e-9,
        settle=config.settle_ticks,
        half=config.velocity_ticks,
    )
    moved = float(np.mean(q[-_ENDS:, joint]) - np.mean(q[:_ENDS, joint])) / float(encoder.quantum[joint])
    return torque, abs(moved) >= _MOVED
