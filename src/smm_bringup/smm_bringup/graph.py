"""The one description of the SMM node graph, used by ``smm-launch`` and by the ROS launch files.

:func:`build_graph` turns :class:`~smm_bringup.graph_options.GraphOptions` into an ordered tuple of
:class:`~smm_bringup.graph_nodes.NodeSpec`, one per process; each spec's parameter files and overrides
follow the precedence of docs/LAUNCH.md. The hardware plant's specs: :mod:`smm_bringup.hardware_graph`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

from smm_controller.controller_node import REFERENCE_PREFIX
from smm_controller.fpdeso import FPDESOConfig
from smm_controller.reference import REFERENCE_KINDS
from smm_controller.td import TrackingDifferentiatorConfig
from smm_hw_bridge.control_rate import control_divider
from smm_schema.fields import config_from_parameters

from smm_bringup.errors import ParameterFileError, PlantNotAvailableError
from smm_bringup.graph_nodes import (
    CONTROLLER_NODE,
    EMULATOR_NODE,
    FLESO_NODE,
    HW_NODE,
    NAMESPACE,
    RECORDER_NODE,
    REFERENCE_NODE,
    SIM_NODE,
    TD_NODE,
    NodeSpec,
    check_parameters,
)
from smm_bringup.graph_options import SCENARIO_NAMES, GraphOptions
from smm_bringup.hardware_graph import emulator_seed, hardware_specs, simulator_settings
from smm_bringup.parameter_files import ParameterValue, load_parameter_file, node_settings, package_file
from smm_bringup.realtime import (
    BOARD_PRIORITY_OFFSET,
    BRIDGE_PRIORITY_OFFSET,
    DEFAULT_HARDWARE_PRIORITY,
    MAX_PRIORITY,
    RECORDER_PRIORITY_OFFSET,
)
from smm_sim.config import PlantParameters

__all__ = [
    "build_graph",
    "control_rate_configs",
    "control_rate_file",
    "control_rate_settings",
    "scenario_file",
]

_CONTROLLER_NODES: Final[tuple[tuple[str, str], ...]] = (
    # (node name = console script, class inside smm_controller.<name>)
    (TD_NODE, "TdNode"),
    (FLESO_NODE, "FlesoNode"),
    (REFERENCE_NODE, "ReferenceNode"),
    (CONTROLLER_NODE, "ControllerNode"),
)
_JOINT_STATES_READERS: Final[tuple[str, ...]] = (TD_NODE, FLESO_NODE, REFERENCE_NODE)
"""Controller-side nodes subscribing ``joint_states`` (controller_node too, when the chain is fused)."""
_SIM_TIME: Final[tuple[tuple[str, ParameterValue], ...]] = (("use_sim_time", True),)
"""The controller side of a lockstep simulator run keeps the simulator's ``/clock`` (docs/LAUNCH.md)."""


def scenario_file(name: str) -> Path:
    """Path of the parameter file of scenario ``name`` (``smm_bringup/config/scenario_<name>.yaml``).

    Raises:
        ValueError: Unknown scenario.
        ParameterFileError: The file is missing.
    """
    if name not in SCENARIO_NAMES:
        raise ValueError(f"scenario must be one of {SCENARIO_NAMES}, got {name!r}")
    return package_file("smm_bringup", f"config/scenario_{name}.yaml")


def control_rate_file(rate_hz: float) -> Path | None:
    """The settings file of control rate ``rate_hz`` (``smm_controller/config/control_rate_<rate>.yaml``).

    None at the board's own rate (1 kHz: the configured defaults are that rate's settings).

    Raises:
        ValueError: Not a control rate (``smm_hw_bridge.control_rate.CONTROL_RATES_HZ``).
        ParameterFileError: The file is missing.
    """
    if control_divider(rate_hz) == 1:
        return None
    return package_file("smm_controller", f"config/control_rate_{rate_hz}.yaml")


def control_rate_settings(rate_hz: float) -> dict[str, Any]:
    """What the settings file of control rate ``rate_hz`` gives ``controller_node`` (empty at 1 kHz)."""
    path = control_rate_file(rate_hz)
    return {} if path is None else load_parameter_file(path, f"/{NAMESPACE}/{CONTROLLER_NODE}")


def control_rate_configs(rate_hz: float) -> tuple[TrackingDifferentiatorConfig, FPDESOConfig]:
    """The TD and FPDESO settings of control rate ``rate_hz``: the defaults with its file's applied."""
    settings = control_rate_settings(rate_hz)
    return (
        config_from_parameters(TrackingDifferentiatorConfig, TrackingDifferentiatorConfig(), settings, "td"),
        config_from_parameters(FPDESOConfig, FPDESOConfig(), settings, "fpdeso"),
    )


def _sim_parameters(options: GraphOptions) -> tuple[tuple[str, ParameterValue], ...]:
    parameters: list[tuple[str, ParameterValue]] = [("clock_mode", options.clock_mode)]
    if options.duration is not None:
        parameters.append(("duration", float(options.duration)))
    elif options.clock_mode == "realtime" and options.scenario is not None:
        # A scenario file sets its length for lockstep runs; in real time the default is no end.
        parameters.append(("duration", 0.0))
    if options.seed is not None:
        parameters.append(("seed", options.seed))
    if options.control_divider > 1:  # the plant integrates at the board's 1 ms step at every control rate
        parameters.append(("substeps", options.control_divider))
    if options.clock_mode == "realtime":  # judged as the hardware path is (exit 3)
        parameters.append(("verdict.late_limit", options.late_limit / 100.0))
    return tuple(parameters) + _period_parameters(options)


def _period_parameters(options: GraphOptions) -> tuple[tuple[str, ParameterValue], ...]:
    """``control_period`` of the nodes stepping once per measurement; none at 1 kHz (as configured)."""
    return () if options.control_divider == 1 else (("control_period", options.control_period),)


def _reference_parameters(files: Sequence[str]) -> tuple[tuple[str, ParameterValue], ...]:
    """The generator parameters the files set for ``reference_node``, renamed ``reference.<name>``.

    So the reference is configured in one place (the ``reference_node`` sections) wherever it is sampled.
    Only ``kind`` and ``<kind>.<field>`` are handed over, not the node's own settings (``lookahead``).
    """
    values = node_settings(files, f"/{NAMESPACE}/{REFERENCE_NODE}")
    return tuple(
        (f"{REFERENCE_PREFIX}.{name}", tuple(value) if isinstance(value, list) else value)
        for name, value in values.items()
        if name == "kind" or name.partition(".")[0] in REFERENCE_KINDS
    )


def _controller_parameters(
    options: GraphOptions, files: Sequence[str]
) -> tuple[tuple[str, ParameterValue], ...]:
    """``controller_node``'s overrides: algorithm, chain placement, reference source, control period."""
    chain = "internal" if options.chain == "fused" else "external"
    parameters = (("algorithm", options.algorithm), ("chain", chain), *_period_parameters(options))
    if options.reference == "controller":
        parameters = (("reference_source", "internal"), *_reference_parameters(files), *parameters)
    return parameters


def build_graph(options: GraphOptions) -> tuple[NodeSpec, ...]:
    """Describe the graph for ``options``: the plant node first, then the controller-side nodes.

    Args:
        options: The user's choices.

    Returns:
        The node specs, in start order.

    Raises:
        PlantNotAvailableError: ``plant="hardware"`` with ``clock_mode="lockstep"`` and a real ``board``.
        ParameterFileError: A scenario or extra parameter file is missing or malformed, or sets a name (or
            has a node section) no node of the stack declares (docs/LAUNCH.md, "Parameter names are
            checked").
    """
    external_frame_board = options.board is not None and options.link != "canopen"  # a CANopen bench steps
    # on the bridge's SYNC: an external one (a second emulator, a HIL rig) can follow it in lockstep
    if options.plant == "hardware" and options.clock_mode == "lockstep" and external_frame_board:
        raise PlantNotAvailableError(
            "a real board runs on its own 1 kHz clock: lockstep needs the emulator (no --board), or use "
            "--clock-mode realtime"
        )
    files: list[str] = []
    if options.scenario is not None:
        files.append(str(scenario_file(options.scenario)))
    rate_file = control_rate_file(options.control_rate)
    if rate_file is not None:
        files.append(str(rate_file))
    for extra in options.params_files:
        path = Path(extra)
        if not path.is_file():
            raise ParameterFileError(f"parameter file {extra} does not exist")
        files.append(str(path.resolve()))
    shared_files = tuple(files)
    direct = _controller_parameters(options, shared_files) if options.loop == "direct" else ()
    plant_side: tuple[NodeSpec, ...] = (
        hardware_specs(options, shared_files, direct)
        if options.plant == "hardware"
        else (
            NodeSpec(
                package="smm_sim",
                executable=SIM_NODE,
                name=SIM_NODE,
                node_class="smm_sim.sim_node:SimNode",
                parameter_files=shared_files,
                parameters=_sim_parameters(options),
            ),
        )
    )
    controller_side = []
    fused = options.chain == "fused"
    reference_in_controller = options.reference == "controller"
    for name, class_name in _CONTROLLER_NODES:
        if fused and name in (TD_NODE, FLESO_NODE):
            continue  # their algorithms run inside controller_node
        if reference_in_controller and name == REFERENCE_NODE:
            continue  # sampled inside controller_node
        if options.loop == "direct" and name == CONTROLLER_NODE:
            continue  # hosted by direct_loop
        parameters = (
            _controller_parameters(options, shared_files)
            if name == CONTROLLER_NODE
            else _period_parameters(options)
        )
        if options.plant == "sim" and options.clock_mode == "lockstep":
            parameters = (*parameters, *_SIM_TIME)
        controller_side.append(
            NodeSpec(
                package="smm_controller",
                executable=name,
                name=name,
                node_class=f"smm_controller.{name}:{class_name}",
                parameter_files=shared_files,
                parameters=parameters,
            )
        )
    recorder: tuple[NodeSpec, ...] = ()
    if options.record is not None:
        recorder = (_recorder_spec(options, shared_files),)
        # Step 0 waits for the recorder (and every node reading joint_states) to be matched.
        readers = sum(spec.name in _JOINT_STATES_READERS for spec in controller_side) + (
            1 if fused and options.loop == "topics" else 0
        )
        gate: tuple[tuple[str, ParameterValue], ...] = ()
        gated = SIM_NODE
        if options.clock_mode == "lockstep" and options.plant == "sim":
            gate = (("start.min_subscribers", readers + 1),)
        elif options.plant == "hardware":  # the bridge arms once they are: the first enabled tick is recorded
            gate, gated = (("autostart_subscribers", readers + 1),), plant_side[-1].name
        plant_side = tuple(
            dataclasses.replace(spec, parameters=spec.parameters + gate) if spec.name == gated else spec
            for spec in plant_side
        )
    specs = tuple(_with_priority(spec, options) for spec in (*recorder, *plant_side, *controller_side))
    for spec in specs:
        check_parameters(spec)
    return specs


def _with_priority(spec: NodeSpec, options: GraphOptions) -> NodeSpec:
    """``spec`` with the SCHED_FIFO priority ``options`` give its process (``GraphOptions.rt_priority``)."""
    priority = options.rt_priority
    if priority is None:
        realtime_hardware = options.plant == "hardware" and options.clock_mode == "realtime"
        priority = DEFAULT_HARDWARE_PRIORITY if realtime_hardware else 0
    if priority and spec.name == EMULATOR_NODE:
        priority = min(MAX_PRIORITY, priority + BOARD_PRIORITY_OFFSET)
    elif priority and spec.name == HW_NODE:
        priority = min(MAX_PRIORITY, priority + BRIDGE_PRIORITY_OFFSET)
    elif priority and spec.name == RECORDER_NODE:
        priority = max(1, priority - RECORDER_PRIORITY_OFFSET)
    return dataclasses.replace(spec, rt_priority=priority)


def _simulator_seed(options: GraphOptions, files: Sequence[str]) -> int | None:
    """The noise seed the simulator runs with: ``--seed``, else the ``files``', else its default."""
    if options.seed is not None:
        return options.seed
    seed = simulator_settings(files).get("seed", PlantParameters().seed)
    return seed if isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0 else None


def _recorder_spec(options: GraphOptions, files: Sequence[str]) -> NodeSpec:
    """``recorder_node`` writing ``options.record``, with the run manifest's entries as parameters."""
    assert options.record is not None
    seed = _simulator_seed(options, files) if options.plant == "sim" else emulator_seed(options)
    parameters: tuple[tuple[str, ParameterValue], ...] = (
        ("output", str(Path(options.record).resolve())),
        ("scenario", options.scenario or ""),
        ("seed", -1 if seed is None else seed),
        ("plant", options.plant),
        ("controller", options.algorithm),
        ("clock_mode", options.clock_mode),
        ("max_size", options.record_max_size),
        ("max_duration", float(options.record_max_duration)),
        *_period_parameters(options),
    )
    return NodeSpec(
        package="smm_bag",
        executable=RECORDER_NODE,
        name=RECORDER_NODE,
        node_class="smm_bag.recorder_node:RecorderNode",
        parameters=parameters,
    )
