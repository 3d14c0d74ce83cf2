"""What the user chooses when starting the SMM graph: :class:`GraphOptions` and the choices it takes.

The options and their meaning for ``smm-launch`` and the launch file: docs/LAUNCH.md.
"""

from __future__ import annotations

import ipaddress
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Final, Literal

from smm_controller.laws import law_names, law_table
from smm_hw_bridge.control_rate import BOARD_TICK_HZ, CONTROL_RATES_HZ, control_divider

from smm_bringup.realtime import MAX_PRIORITY

__all__ = [
    "CANOPEN_REALTIME_RATE_HZ",
    "CHAIN_LAYOUTS",
    "CLOCK_MODES",
    "CONTROL_RATES_HZ",
    "EXTERNAL_BOARD",
    "LINKS",
    "LOOPS",
    "PLANTS",
    "PLANT_ALIASES",
    "RECORD_SPLIT_DURATIONS",
    "RECORD_SPLIT_SIZES",
    "REFERENCE_PLACEMENTS",
    "SCENARIO_NAMES",
    "GraphOptions",
    "default_control_rate",
    "split_endpoint",
]

PLANTS: Final[tuple[str, ...]] = ("sim", "hardware")
PLANT_ALIASES: Final[Mapping[str, str]] = MappingProxyType({"hw": "hardware"})
"""Other names accepted for a plant (``hw`` = ``hardware``)."""
CLOCK_MODES: Final[tuple[str, ...]] = ("lockstep", "realtime")
LINKS: Final[tuple[str, ...]] = ("frame", "canopen")
"""The hardware plant's link: ``frame`` (the I/O board's frame protocol, docs/HW_PROTOCOL.md) or ``canopen``
(CiA 408 valves and CiA 406 encoders, docs/HW_CANOPEN.md)."""
CANOPEN_REALTIME_RATE_HZ: Final[int] = 200
"""The CANopen link's default control rate in real time (the host's loop sends each SYNC; measured to hold
on a loaded 2-core machine, docs/HW_CANOPEN.md, "Real time"); lockstep keeps 1000 Hz."""
EXTERNAL_BOARD: Final[str] = "external"
"""``board`` on the CANopen link: no emulator; the bridge drives the devices its ``canopen.*`` name."""
LOOPS: Final[tuple[str, ...]] = ("auto", "topics", "direct")
"""``topics``: the plant and ``controller_node`` are separate processes joined by topics (the product's
shape); ``direct`` (hardware only): one process, ``direct_loop``, steps the chain of ``controller_node`` in
the bridge's receiving thread and publishes the same topics for observation (docs/LAUNCH.md); ``auto``: the
direct loop for the hardware plant in real time (it holds the deadline best) where the chain and reference
allow it, the topics loop otherwise."""
CHAIN_LAYOUTS: Final[tuple[str, ...]] = ("fused", "split")
"""``fused``: TD, FLESO and law in ``controller_node`` (``chain: internal``), two hops per step; ``split``:
``td_node`` and ``fleso_node`` as their own nodes (``chain: external``), four hops per step."""
REFERENCE_PLACEMENTS: Final[tuple[str, ...]] = ("node", "controller")
"""``node``: ``reference_node`` publishes the reference, ``controller_node`` matches it by stamp;
``controller``: ``controller_node`` samples it itself (``reference_source: internal``), from the parameters
that the parameter files give ``reference_node``, and no ``reference_node`` runs."""
SCENARIO_NAMES: Final[tuple[str, ...]] = ("step", "case1", "case2", "excite")
RECORD_SPLIT_SIZES: Final[tuple[int, int]] = (64 * 1024, 1 << 40)
"""Range of ``record_max_size`` (bytes) besides 0: the writer's smallest split size, 1 TiB."""
RECORD_SPLIT_DURATIONS: Final[tuple[float, float]] = (1.0, 86_400.0)
"""Range of ``record_max_duration`` (s) besides 0: one second (a file per step would be absurd), one day."""


@dataclass(frozen=True)
class GraphOptions:
    """What the user chooses when starting the graph.

    Attributes:
        plant: ``"sim"`` (smm_sim_node) or ``"hardware"`` (``hw_bridge_node``, configured and activated,
            and the bench emulator unless ``board`` is given; ``"hw"`` is accepted for it).
        clock_mode: ``"lockstep"`` (deterministic, as fast as the graph allows, /clock published by the
            simulator) or ``"realtime"`` (wall-clock timer at the control period).
        chain: ``"fused"`` (default): ``controller_node`` runs TD -> FLESO -> law itself, so a step crosses
            two process boundaries (plant -> controller -> plant), the layout that keeps up with 1 kHz;
            ``"split"``: ``td_node`` and ``fleso_node`` run as their own nodes (four crossings per step), to
            inspect or replace a stage on the wire. Both give the same torques.
        reference: ``"controller"`` (default): ``controller_node`` samples the reference itself, one input
            and one process less per step, so the default graph is plant + controller; ``"node"``:
            ``reference_node`` publishes it one period ahead. The same values either way (see
            :data:`REFERENCE_PLACEMENTS`).
        algorithm: Controller algorithm, a law of ``smm_controller.laws.law_table()``.
        scenario: Scenario name (:data:`SCENARIO_NAMES`), or ``None`` for the nodes' own defaults.
        duration: Simulated time after which the simulator stops (s), > 0; ``None`` keeps the scenario's
            length in lockstep and runs without end in real time; 0 runs without end.
        seed: Seed of the simulator's noise generator, >= 0; ``None`` keeps the configured one.
        params_files: Extra ROS 2 parameter files, applied after the scenario file, in order.
        control_rate: Control rate (Hz), one of ``smm_hw_bridge.control_rate.CONTROL_RATES_HZ`` (1000, 500,
            250, 200, 100). The board (and the simulator's integration step) keeps its 1 kHz tick; the
            controller steps every N = 1000 / rate ticks with ``control_period`` = N ms, the board holds each
            command in between, and the rate's settings file
            (``smm_controller/config/control_rate_<rate>.yaml``) is applied after the scenario's
            (docs/LAUNCH.md, "Control rate").
        board: ``hardware`` only: ``ADDRESS:PORT`` of the bench's I/O board (``external`` on the CANopen
            link: the devices its parameters name); ``None`` starts ``smm_bench_emulator`` on loopback.
        link: ``hardware`` only: ``frame`` or ``canopen`` (:data:`LINKS`).
        bench_file: ``hardware`` with the emulator only (either link): the bench description it runs
            (docs/BENCH.md), made absolute; the scenario's plant settings (noise, disturbance, inertia
            scale) override its fields; on CANopen the bridge states its supply (``canopen.supply_bar``).
            ``None``: the emulator's defaults.
        record: Bag folder for ``recorder_node`` (smm_bag), started before the other nodes and stopped
            after them; ``None`` records nothing.
        record_max_size: Start a new bag file when the current one reaches this many bytes: 0 (never) or
            in [RECORD_MIN_SPLIT_SIZE, RECORD_MAX_SPLIT_SIZE] (64 KiB .. 1 TiB).
        record_max_duration: Start a new bag file after this many seconds of messages: 0 (never) or in
            [RECORD_MIN_SPLIT_DURATION, RECORD_MAX_SPLIT_DURATION] (1 s .. 1 day).
        loop: ``"auto"`` (default), ``"topics"`` or ``"direct"`` (``plant="hardware"``, fused chain,
            reference sampled by the controller): see :data:`LOOPS`. ``"auto"`` is resolved on
            construction, so the instance holds ``"topics"`` or ``"direct"``.
        late_limit: ``hardware``, and the simulator in real time: percent of the ticks after the first second
            of live output that may be late or not live before the run counts as not controlled (exit 3,
            docs/LAUNCH.md), in [0, 100].
        preflight: ``hardware`` in real time: seconds the bridge rehearses the loop with output disabled
            before arming (``preflight.duration_s``, in [0, 30], 0 skips it); ``None``: its default (3 s).
        force: ``hardware``: arm even when the preflight finds the control rate is not held (a warning).
        start_timeout: ``hardware``: seconds the emulator waits for the first step (lockstep) or the first
            tick with an enabled command (real time) before the run counts as never started (exit 3), > 0.
        rt_priority: SCHED_FIFO priority (1-98) of the processes of the loop (plant or bridge, controller
            nodes), 0 for normal scheduling; ``None``: 50 with ``plant="hardware"`` in real time (as
            ros2_control's controller manager), 0 with the simulator. The bench emulator, standing for the
            hard real-time board, runs 20 above (at most 99); the recorder 10 below (at least 1): above
            every ordinary process, so that a loaded host does not starve it, below the loop. Where the
            system refuses SCHED_FIFO, the launcher says so and runs them at normal priority. Lockstep: 0
            by default.
    """

    plant: Literal["sim", "hardware", "hw"] = "sim"
    clock_mode: Literal["lockstep", "realtime"] = "lockstep"
    chain: Literal["fused", "split"] = "fused"
    reference: Literal["node", "controller"] = "controller"
    algorithm: str = "fpdeso"
    scenario: str | None = "case2"
    duration: float | None = None
    seed: int | None = None
    params_files: tuple[str, ...] = ()
    control_rate: float = BOARD_TICK_HZ
    board: str | None = None
    link: Literal["frame", "canopen"] = "frame"
    bench_file: str | None = None
    record: str | None = None
    record_max_size: int = 0
    record_max_duration: float = 0.0
    rt_priority: int | None = None
    loop: Literal["auto", "topics", "direct"] = "auto"
    late_limit: float = 1.0
    start_timeout: float = 60.0
    preflight: float | None = None
    force: bool = False
    loop_note: str | None = field(default=None, init=False, compare=False)
    """Why ``auto`` chose the topics loop for a hardware run in real time (the user's chain or reference),
    in one line; None otherwise."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "plant", PLANT_ALIASES.get(self.plant, self.plant))
        if self.plant not in PLANTS:
            raise ValueError(f"plant must be one of {PLANTS}, got {self.plant!r}")
        if self.clock_mode not in CLOCK_MODES:
            raise ValueError(f"clock_mode must be one of {CLOCK_MODES}, got {self.clock_mode!r}")
        if self.chain not in CHAIN_LAYOUTS:
            raise ValueError(f"chain must be one of {CHAIN_LAYOUTS}, got {self.chain!r}")
        if self.reference not in REFERENCE_PLACEMENTS:
            raise ValueError(f"reference must be one of {REFERENCE_PLACEMENTS}, got {self.reference!r}")
        if self.algorithm not in law_table():
            raise ValueError(f"algorithm must be one of {law_names()}, got {self.algorithm!r}")
        if self.scenario is not None and self.scenario not in SCENARIO_NAMES:
            raise ValueError(f"scenario must be one of {SCENARIO_NAMES} or None, got {self.scenario!r}")
        if self.duration is not None and (
            isinstance(self.duration, bool)
            or not isinstance(self.duration, (int, float))
            or not math.isfinite(self.duration)
            or self.duration < 0.0
        ):
            raise ValueError(f"duration must be a finite number >= 0 s or None, got {self.duration!r}")
        control_divider(self.control_rate)  # raises with the valid rates
        object.__setattr__(self, "control_rate", int(self.control_rate))  # 500.0 (argparse) is 500
        seed = self.seed
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
            raise ValueError(f"seed must be an int >= 0 or None, got {self.seed!r}")
        if self.record is not None and (not isinstance(self.record, str) or not self.record.strip()):
            raise ValueError(f"record must be a bag folder path or None, got {self.record!r}")
        _check_split("record_max_size", self.record_max_size, RECORD_SPLIT_SIZES, integer=True)
        _check_split("record_max_duration", self.record_max_duration, RECORD_SPLIT_DURATIONS, integer=False)
        if (self.record_max_size or self.record_max_duration) and self.record is None:
            raise ValueError("record_max_size and record_max_duration are options of record (a bag folder)")
        priority = self.rt_priority
        if priority is not None and (
            isinstance(priority, bool) or not isinstance(priority, int) or not 0 <= priority < MAX_PRIORITY
        ):
            raise ValueError(
                f"rt_priority must be an int in [0, {MAX_PRIORITY - 1}] or None, got {priority!r}"
            )
        for name, wanted in (("late_limit", "a percentage in [0, 100]"), ("start_timeout", "> 0 s")):
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float))
                or not math.isfinite(value)
                or not (0.0 <= value <= 100.0 if name == "late_limit" else value > 0.0)
            ):
                raise ValueError(f"{name} must be a finite number, {wanted}, got {value!r}")
        preflight = self.preflight
        if preflight is not None and (
            isinstance(preflight, bool)
            or not isinstance(preflight, (int, float))
            or not 0.0 <= preflight <= 30.0
        ):
            raise ValueError(f"preflight must be a number of seconds in [0, 30] or None, got {preflight!r}")
        if not isinstance(self.force, bool):
            raise ValueError(f"force must be a bool, got {self.force!r}")
        if self.loop not in LOOPS:
            raise ValueError(f"loop must be one of {LOOPS}, got {self.loop!r}")
        if self.loop == "auto":
            self._choose_loop()
        if self.loop == "direct" and (
            self.plant != "hardware" or self.chain != "fused" or self.reference != "controller"
        ):
            raise ValueError(
                "loop 'direct' runs the whole chain in the bridge's process: it needs plant 'hardware', "
                "chain 'fused' and reference 'controller'"
            )
        if self.link not in LINKS:
            raise ValueError(f"link must be one of {LINKS}, got {self.link!r}")
        if self.link == "canopen" and self.plant != "hardware":
            raise ValueError("link 'canopen' needs plant 'hardware'")
        if self.board is not None:
            if self.plant != "hardware":
                raise ValueError("board is an option of plant 'hardware' only")
            if self.seed is not None:
                raise ValueError(
                    "seed seeds the simulator's or the emulator's noise: with board, there is none"
                )
            if self.link == "canopen":
                if self.board != EXTERNAL_BOARD:
                    raise ValueError(
                        f"board on link 'canopen' is {EXTERNAL_BOARD!r} or none, got {self.board!r}"
                    )
            else:
                split_endpoint("board", self.board)
        if self.bench_file is not None:
            if not isinstance(self.bench_file, str) or not self.bench_file.strip():
                raise ValueError(f"bench_file must be a file path or None, got {self.bench_file!r}")
            if self.plant != "hardware" or self.board is not None:
                raise ValueError("bench_file is an option of plant 'hardware' with the emulator (no board)")
            object.__setattr__(self, "bench_file", os.path.abspath(self.bench_file))

    def _choose_loop(self) -> None:
        """``loop="auto"``: direct for the hardware plant in real time unless the choices forbid it."""
        hardware_realtime = self.plant == "hardware" and self.clock_mode == "realtime"
        unhosted = [
            f"--{name} {value}"
            for name, value, wanted in (
                ("chain", self.chain, "fused"),
                ("reference", self.reference, "controller"),
            )
            if value != wanted
        ]
        loop = "direct" if hardware_realtime and not unhosted else "topics"
        object.__setattr__(self, "loop", loop)
        if hardware_realtime and unhosted:
            object.__setattr__(
                self,
                "loop_note",
                f"the direct loop cannot host {' '.join(unhosted)}: using the topics loop",
            )

    @property
    def control_divider(self) -> int:
        """N, board ticks per control period (1 at 1 kHz)."""
        return control_divider(self.control_rate)

    @property
    def control_period(self) -> float:
        """The controller's period (s): N board ticks."""
        return self.control_divider / BOARD_TICK_HZ


def default_control_rate(link: str, clock_mode: str) -> int:
    """The control rate smm-launch and the launch file use when none is given (Hz)."""
    return CANOPEN_REALTIME_RATE_HZ if link == "canopen" and clock_mode == "realtime" else BOARD_TICK_HZ


def _check_split(name: str, value: object, limits: tuple[float, float], *, integer: bool) -> None:
    """Rejects a split option that is not 0 nor a number in ``limits`` (an int where ``integer``)."""
    low, high = limits
    kind = (int,) if integer else (int, float)
    if (
        isinstance(value, bool)
        or not isinstance(value, kind)
        or not math.isfinite(value)
        or not (value == 0 or low <= value <= high)
    ):
        unit = "bytes" if integer else "s"
        raise ValueError(f"{name} must be 0 (never split) or in [{low:g}, {high:g}] {unit}, got {value!r}")


def split_endpoint(name: str, text: str) -> tuple[str, int]:
    """``"ADDRESS:PORT"`` -> (IPv4 address, port).

    Raises:
        ValueError: not an IPv4 address and a port in [1, 65535] (message names ``name``).
    """
    host, _, port = str(text).rpartition(":")
    try:
        address = str(ipaddress.IPv4Address(host))
    except ValueError as error:
        raise ValueError(f"{name} must be IPV4ADDRESS:PORT, got {text!r}") from error
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"{name} must be IPV4ADDRESS:PORT with a port in [1, 65535], got {text!r}")
    return address, int(port)
