"""The hardware plant's processes of the SMM graph: ``hw_bridge_node`` (or ``direct_loop``) and the emulator.

How ``--plant hardware``, ``--board`` and ``--loop direct`` start them: docs/LAUNCH.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Final

from smm_bench_emulator.bench_file import BenchFileError, default_bench, load_bench_file
from smm_bench_emulator.board import BoardConfig
from smm_bench_emulator.canopen_bench import eds_path
from smm_hw_bridge.canopen_config import parameter as canopen_parameter
from smm_hw_bridge.cia408 import SPOOL_FULL_SCALE

from smm_bringup.errors import ParameterFileError
from smm_bringup.graph_nodes import (
    CONTROLLER_NODE,
    DIRECT_LOOP,
    EMULATOR_NODE,
    HW_NODE,
    NAMESPACE,
    SIM_NODE,
    NodeSpec,
)
from smm_bringup.graph_options import GraphOptions, split_endpoint
from smm_bringup.parameter_files import ParameterValue, node_settings

__all__ = ["EMULATOR_BOARD", "EMULATOR_HOST", "emulator_seed", "hardware_specs", "simulator_settings"]

EMULATOR_BOARD: Final[str] = "127.0.0.1:50101"
EMULATOR_HOST: Final[str] = "127.0.0.1:50100"
"""Loopback addresses of the emulated board and of the bridge when no board address is given."""


def hardware_specs(
    options: GraphOptions,
    files: Sequence[str],
    controller: Sequence[tuple[str, ParameterValue]] = (),
) -> tuple[NodeSpec, ...]:
    """``hw_bridge_node`` (autostart), after ``smm_bench_emulator`` unless a board address is given.

    The bridge reads the parameter ``files`` (``bridge.*`` of its node key), as the direct loop does.

    The emulator gets the plant the parameter ``files`` give the simulator (noise, disturbance, inertias).
    With ``options.loop == "direct"``, ``direct_loop`` replaces the bridge: it hosts ``controller_node``
    too, with the overrides ``controller``.
    """
    canopen = options.link == "canopen"
    board = options.board or EMULATOR_BOARD
    bridge_parameters: list[tuple[str, ParameterValue]] = [
        ("autostart", True),
        *(_canopen_link(options, files) if canopen else _frame_link(board)),
        ("verdict.late_limit", options.late_limit / 100.0),
    ]
    if options.preflight is not None:
        bridge_parameters.append(("preflight.duration_s", float(options.preflight)))
    if options.force:
        bridge_parameters.append(("preflight.force", True))
    lockstep = options.clock_mode == "lockstep"
    if lockstep:
        # The board ticks when the controller has answered: the graph's pace, no wall-clock limit may fire.
        bridge_parameters += [
            ("bridge.lockstep", True),
            ("bridge.host_watchdog_ns", 10_000_000_000),
            ("bridge.link_timeout_ns", 60_000_000_000),
            ("bridge.admission.stale_ns", 60_000_000_000),
            ("link.configure_timeout", min(float(options.start_timeout), 600.0)),
        ]
    if options.board is None and not canopen:
        bind_address, bind_port = split_endpoint("host", EMULATOR_HOST)
        bridge_parameters += [("link.bind_address", bind_address), ("link.bind_port", bind_port)]
    duration = options.duration
    if duration is None and lockstep:
        duration = _scenario_duration(files)  # as the simulator: the scenario's length in lockstep
    if duration and options.board is None:  # the emulated bench falls silent at its end, not a fault
        bridge_parameters.append(("verdict.planned_s", float(duration)))
    elif options.duration and options.board is not None:  # nothing else ends an external board's run
        bridge_parameters += [("verdict.planned_s", float(options.duration)), ("verdict.ends_run", True)]
    divider = options.control_divider
    if divider > 1:  # the board keeps its 1 kHz tick; the bridge stretches validity and limits by N
        bridge_parameters.append(("bridge.control_divider", divider))
    bridge = NodeSpec(
        package="smm_hw_bridge",
        executable=HW_NODE,
        name=HW_NODE,
        node_class="smm_hw_bridge.bridge_node:HwBridgeNode",
        parameter_files=tuple(files),  # --params-file reaches the bridge (its valve and encoder truths)
        parameters=tuple(bridge_parameters),
    )
    if options.loop == "direct":
        bridge = NodeSpec(
            package="smm_direct_loop",
            executable=DIRECT_LOOP,
            name=DIRECT_LOOP,
            node_class="",  # two nodes in one process, a thread of its own: a process, never composed
            parameter_files=tuple(files),
            parameters=(*bridge_parameters, *controller),
            hosts=(CONTROLLER_NODE, HW_NODE),
        )
    if options.board is not None:
        return (bridge,)
    emulator_parameters: list[tuple[str, ParameterValue]] = (
        [("link", "canopen")]
        if canopen
        else [("bind", board), ("host", EMULATOR_HOST), ("late-limit", float(options.late_limit))]
    )
    if duration:
        emulator_parameters.append(("duration", float(duration)))
    emulator_parameters.append(("start-timeout", float(options.start_timeout)))
    if lockstep:
        emulator_parameters += [
            ("mode", "lockstep"),
            ("lockstep-trigger", "enabled"),  # tick 0 waits for the controller, as the simulator's step 0
        ]
    else:  # a host slow to start (a loaded machine) shortens no run
        emulator_parameters.append(("duration-from", "live"))
    if options.seed is not None:
        emulator_parameters.append(("seed", options.seed))
    if divider > 1:
        emulator_parameters.append(("control-divider", divider))
    if options.bench_file is not None:
        emulator_parameters.append(("bench-file", options.bench_file))
    emulator_parameters += _emulator_plant(files)  # options: the scenario's settings override the bench file
    emulator = NodeSpec(
        package="smm_bench_emulator",
        executable=EMULATOR_NODE,
        name=EMULATOR_NODE,
        node_class="",  # a plain process (the board side), not a ROS node: no composed mode
        parameters=tuple(emulator_parameters),
    )
    return (emulator, bridge)


def emulator_seed(options: GraphOptions) -> int | None:
    """The seed the emulator runs with: ``--seed``, else its bench file's, else its default.

    None when no single seed is known: an external board (``options.board``), or a bench file whose A/D
    ``seed`` and ``plant.seed`` differ (or that the emulator will refuse).
    """
    if options.board is not None:
        return None
    if options.seed is not None:
        return options.seed
    bench = _emulated_bench(options)
    return None if bench is None or bench.seed != bench.plant.seed else bench.seed


def _emulated_bench(options: GraphOptions) -> BoardConfig | None:
    """The bench the emulator runs: its bench file's, else the default; None if it will refuse the file."""
    try:
        return default_bench() if options.bench_file is None else load_bench_file(options.bench_file)
    except BenchFileError:  # the emulator refuses it with its reason (exit 2): no run
        return None


def _frame_link(board: str) -> list[tuple[str, ParameterValue]]:
    address, port = split_endpoint("board", board)
    return [("link.board_address", address), ("link.board_port", port)]


def _canopen_link(options: GraphOptions, files: Sequence[str]) -> list[tuple[str, ParameterValue]]:
    """``link.transport: canopen``; with the emulated bench, its EDS files and supply (else the user's).

    The valve units (gain from the nominal valve's full-scale torque, code and rate limits) apply only where
    the parameter ``files`` set none for the bridge: a file's valve truths win, as on the frame link (a bench
    file's truths are not told to the host: commissioning finds them).
    """
    link: list[tuple[str, ParameterValue]] = [("link.transport", "canopen")]
    if options.board is None:
        bench = _emulated_bench(options)
        if bench is not None:  # no node sends the supply: the bridge states the emulated bench's
            link.append((canopen_parameter("supply_bar"), bench.supply_pressure))
        full_scale = BoardConfig().full_scale_torque  # the nominal valve's, as the frame link's default
        link += [
            (canopen_parameter("valve_eds"), str(eds_path("valve_cia408.eds"))),
            (canopen_parameter("encoder_eds"), str(eds_path("encoder_cia406.eds"))),
        ]
        user = node_settings(files, f"/{NAMESPACE}/{HW_NODE}")
        # the valves' units: spool +-16384 = +-100 % = the nominal valve's full-scale torque; the rate
        # limit as the frame link's default, full scale in 2 ms
        units: list[tuple[str, ParameterValue]] = [
            ("bridge.valve.gain", tuple(SPOOL_FULL_SCALE / torque for torque in full_scale)),
            ("bridge.valve.code_limit", (SPOOL_FULL_SCALE, SPOOL_FULL_SCALE)),
            ("bridge.valve.rate_limit", (SPOOL_FULL_SCALE / 0.002,) * 2),
        ]
        link += [(name, value) for name, value in units if name not in user]
    divider = options.control_divider
    if divider > 1:  # one SYNC a control period; a valve's receive deadline of 10 periods, as at 1 kHz
        link += [
            (canopen_parameter("period_us"), 1000 * divider),
            (canopen_parameter("receive_deadline_ms"), 10 * divider),
        ]
    if options.clock_mode == "lockstep":
        # the controller's pace, a loaded machine's: generous validity and heartbeat consumer times
        link += [
            (canopen_parameter("sync_on_enabled"), True),
            (canopen_parameter("pdo_validity_ms"), 60_000),
            (canopen_parameter("heartbeat_ms"), 1000),
        ]
    else:  # the bridge's loop sends each SYNC when due (docs/HW_CANOPEN.md, "Real time")
        link.append((canopen_parameter("sync_clock"), True))
    return link


def simulator_settings(files: Sequence[str]) -> dict[str, Any]:
    """What the parameter ``files`` set for the simulator (its section of each, later files winning)."""
    return node_settings(files, f"/{NAMESPACE}/{SIM_NODE}")


def _scenario_duration(files: Sequence[str]) -> float | None:
    """The simulator's ``duration`` the parameter ``files`` set (s), None if none."""
    value = simulator_settings(files).get("duration")
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _emulator_plant(files: Sequence[str]) -> list[tuple[str, ParameterValue]]:
    """The emulator's plant options from the simulator's settings in the parameter ``files``.

    Raises:
        ParameterFileError: A per-joint noise the emulator cannot take (it takes one std for both joints).
    """
    sim = simulator_settings(files)
    options: list[tuple[str, ParameterValue]] = []
    if "noise_std" in sim:
        noise = sim["noise_std"]
        if not isinstance(noise, list) or len(noise) != 2 or noise[0] != noise[1]:
            raise ParameterFileError(
                f"{SIM_NODE}.noise_std {noise!r}: the bench emulator takes one noise std for both joints"
            )
        options.append(("noise-std", float(noise[0])))
    if "inertia_scale" in sim:
        options.append(("inertia-scale", float(sim["inertia_scale"])))
    if "disturbance" in sim:
        options.append(("disturbance", str(sim["disturbance"])))
    return options
