"""The one description of the SMM node graph, used by ``smm-launch`` and by the ROS launch files.

:func:`build_graph` turns :class:`GraphOptions` (plant, clock mode, chain layout, algorithm, scenario,
duration, seed, extra parameter files) into an ordered tuple of :class:`NodeSpec`: package, executable,
node name, namespace, parameter files, parameter overrides and remappings of each node. ``smm-launch``
starts each spec as its own OS process (:meth:`NodeSpec.command_line`) or, with ``--composed``,
instantiates the node classes in one process (:attr:`NodeSpec.node_class`, :func:`parameter_overrides`);
the launch files map the same specs onto ``launch_ros.actions.Node``. So the two ways to start the graph
cannot drift apart.

Parameter precedence, lowest first (later layers win, as in ``ros2 launch``): the node's own defaults,
the scenario file ``smm_bringup/config/scenario_<name>.yaml``, the user's extra ``--params-file`` files in
the order given, then the overrides that the launcher's own options imply (clock mode, duration, seed,
algorithm).

A scenario file holds what the scenario of :mod:`smm_analysis.scenarios` defines (plant noise,
disturbance, model error, duration; reference kind, amplitude, frequency), one section per node. The
files are data, so a user can write a new scenario without code; a test checks that the shipped files
agree with :mod:`smm_analysis.scenarios`.
"""

from __future__ import annotations

import dataclasses
import importlib
import ipaddress
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any, Final, Literal

from smm_controller.controller_node import REFERENCE_PREFIX
from smm_controller.reference import REFERENCE_KINDS

from smm_bringup.errors import ParameterFileError, PlantNotAvailableError
from smm_bringup.parameter_files import (
    ParameterValue,
    format_parameter_value,
    load_parameter_file,
    package_file,
)
from smm_bringup.realtime import (
    BOARD_PRIORITY_OFFSET,
    BRIDGE_PRIORITY_OFFSET,
    DEFAULT_HARDWARE_PRIORITY,
    MAX_PRIORITY,
    RECORDER_PRIORITY_OFFSET,
)
from smm_msgs_py import topics

__all__ = [
    "ALGORITHMS",
    "CHAIN_LAYOUTS",
    "CLOCK_MODES",
    "CONTROLLER_NODE",
    "DIRECT_LOOP",
    "EMULATOR_NODE",
    "FLESO_NODE",
    "HW_NODE",
    "LOOPS",
    "NAMESPACE",
    "PLANTS",
    "PLANT_ALIASES",
    "PLANT_NODE_NAMES",
    "RECORDER_NODE",
    "REFERENCE_NODE",
    "REFERENCE_PLACEMENTS",
    "SCENARIO_NAMES",
    "SIM_NODE",
    "TD_NODE",
    "GraphOptions",
    "NodeSpec",
    "build_graph",
    "parameter_overrides",
    "scenario_file",
    "split_endpoint",
]

NAMESPACE: Final[str] = "smm"
"""Namespace of every node of the graph (topics resolve to ``/smm/<topic>``)."""

PLANTS: Final[tuple[str, ...]] = ("sim", "hardware")
PLANT_ALIASES: Final[Mapping[str, str]] = MappingProxyType({"hw": "hardware"})
"""Other names accepted for a plant (``hw`` = ``hardware``)."""
EMULATOR_BOARD: Final[str] = "127.0.0.1:50101"
EMULATOR_HOST: Final[str] = "127.0.0.1:50100"
"""Loopback addresses of the emulated board and of the bridge when no board address is given."""
CLOCK_MODES: Final[tuple[str, ...]] = ("lockstep", "realtime")
LOOPS: Final[tuple[str, ...]] = ("topics", "direct")
"""``topics``: the plant and ``controller_node`` are separate processes joined by topics (the product's
shape); ``direct`` (hardware only): one process, ``direct_loop``, steps the chain of ``controller_node`` in
the bridge's receiving thread and publishes the same topics for observation (docs/LAUNCH.md)."""
CHAIN_LAYOUTS: Final[tuple[str, ...]] = ("fused", "split")
"""``fused``: TD, FLESO and law in ``controller_node`` (``chain: internal``), two hops per step; ``split``:
``td_node`` and ``fleso_node`` as their own nodes (``chain: external``), four hops per step."""
REFERENCE_PLACEMENTS: Final[tuple[str, ...]] = ("node", "controller")
"""``node``: ``reference_node`` publishes the reference, ``controller_node`` matches it by stamp;
``controller``: ``controller_node`` samples it itself (``reference_source: internal``), from the parameters
that the parameter files give ``reference_node``, and no ``reference_node`` runs."""
ALGORITHMS: Final[tuple[str, ...]] = ("fpdeso", "fpd", "pid", "npd")
SCENARIO_NAMES: Final[tuple[str, ...]] = ("step", "case1", "case2", "excite")


SIM_NODE: Final[str] = "smm_sim_node"
HW_NODE: Final[str] = "hw_bridge_node"
EMULATOR_NODE: Final[str] = "smm_bench_emulator"
TD_NODE: Final[str] = "td_node"
FLESO_NODE: Final[str] = "fleso_node"
REFERENCE_NODE: Final[str] = "reference_node"
CONTROLLER_NODE: Final[str] = "controller_node"
RECORDER_NODE: Final[str] = "recorder_node"
DIRECT_LOOP: Final[str] = "direct_loop"
"""The direct loop's process (console script of ``smm_direct_loop``), hosting HW_NODE and CONTROLLER_NODE."""

PLANT_NODE_NAMES: Final[frozenset[str]] = frozenset((SIM_NODE, HW_NODE, EMULATOR_NODE))
"""Names of the plant processes: when one of them exits 0 the run is complete (see ``docs/LAUNCH.md``);
with the emulator that is the end of its ``duration``."""

_CONTROLLER_NODES: Final[tuple[tuple[str, str], ...]] = (
    # (node name = console script, class inside smm_controller.<name>)
    (TD_NODE, "TdNode"),
    (FLESO_NODE, "FlesoNode"),
    (REFERENCE_NODE, "ReferenceNode"),
    (CONTROLLER_NODE, "ControllerNode"),
)
_JOINT_STATES_READERS: Final[tuple[str, ...]] = (TD_NODE, FLESO_NODE, REFERENCE_NODE)
"""Controller-side nodes subscribing ``joint_states`` (controller_node too, when the chain is fused)."""
_PUBLISHED: Final[dict[str, tuple[str, ...]]] = {
    CONTROLLER_NODE: (topics.TORQUE_COMMAND, topics.CONTROLLER_INTERNALS),
    TD_NODE: (topics.JOINT_STATES_FILTERED,),
    FLESO_NODE: (topics.DISTURBANCE_ESTIMATE, topics.OBSERVER_STATE),
    REFERENCE_NODE: (topics.REFERENCE,),
    DIRECT_LOOP: (
        topics.TORQUE_COMMAND,
        topics.CONTROLLER_INTERNALS,
        topics.JOINT_STATES,
        topics.HW_BRIDGE_INTERNALS,
    ),
}
"""The recorded stack topics each controller-side node publishes (besides ``/diagnostics``)."""


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
        algorithm: Controller algorithm, one of :data:`ALGORITHMS`.
        scenario: Scenario name (:data:`SCENARIO_NAMES`), or ``None`` for the nodes' own defaults.
        duration: Simulated time after which the simulator stops (s), > 0; ``None`` keeps the scenario's
            length in lockstep and runs without end in real time; 0 runs without end.
        seed: Seed of the simulator's noise generator, >= 0; ``None`` keeps the configured one.
        params_files: Extra ROS 2 parameter files, applied after the scenario file, in order.
        control_period: Control period of every node (s), > 0; ``None`` keeps the configured one (1 ms).
            The plant and the controller nodes must agree on it: each node steps once per measurement.
        board: ``hardware`` only: ``ADDRESS:PORT`` of the bench's I/O board; ``None`` starts
            ``smm_bench_emulator`` on loopback instead.
        record: Bag folder for ``recorder_node`` (smm_bag), started before the other nodes and stopped
            after them; ``None`` records nothing.
        loop: ``"topics"`` (default) or ``"direct"`` (``plant="hardware"``, fused chain, reference sampled
            by the controller): see :data:`LOOPS`.
        rt_priority: SCHED_FIFO priority (1-98) of the processes of the loop (plant or bridge, controller
            nodes), 0 for normal scheduling; ``None``: 50 with ``plant="hardware"`` (as ros2_control's
            controller manager), 0 with the simulator. The bench emulator, standing for the hard real-time
            board, runs 20 above (at most 99); the recorder 10 below (at least 1): above every ordinary
            process, so that a loaded host does not starve it, below the loop. Where the system refuses
            SCHED_FIFO, the launcher says so and runs them at normal priority.
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
    control_period: float | None = None
    board: str | None = None
    record: str | None = None
    rt_priority: int | None = None
    loop: Literal["topics", "direct"] = "topics"

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
        if self.algorithm not in ALGORITHMS:
            raise ValueError(f"algorithm must be one of {ALGORITHMS}, got {self.algorithm!r}")
        if self.scenario is not None and self.scenario not in SCENARIO_NAMES:
            raise ValueError(f"scenario must be one of {SCENARIO_NAMES} or None, got {self.scenario!r}")
        if self.duration is not None and (
            isinstance(self.duration, bool)
            or not isinstance(self.duration, (int, float))
            or not math.isfinite(self.duration)
            or self.duration < 0.0
        ):
            raise ValueError(f"duration must be a finite number >= 0 s or None, got {self.duration!r}")
        period = self.control_period
        if period is not None and (
            isinstance(period, bool)
            or not isinstance(period, (int, float))
            or not math.isfinite(period)
            or round(period * 1e9) < 1
        ):
            raise ValueError(f"control_period must be a finite number >= 1 ns or None, got {period!r}")
        seed = self.seed
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
            raise ValueError(f"seed must be an int >= 0 or None, got {self.seed!r}")
        if self.record is not None and (not isinstance(self.record, str) or not self.record.strip()):
            raise ValueError(f"record must be a bag folder path or None, got {self.record!r}")
        priority = self.rt_priority
        if priority is not None and (
            isinstance(priority, bool) or not isinstance(priority, int) or not 0 <= priority < MAX_PRIORITY
        ):
            raise ValueError(
                f"rt_priority must be an int in [0, {MAX_PRIORITY - 1}] or None, got {priority!r}"
            )
        if self.loop not in LOOPS:
            raise ValueError(f"loop must be one of {LOOPS}, got {self.loop!r}")
        if self.loop == "direct" and (
            self.plant != "hardware" or self.chain != "fused" or self.reference != "controller"
        ):
            raise ValueError(
                "loop 'direct' runs the whole chain in the bridge's process: it needs plant 'hardware', "
                "chain 'fused' and reference 'controller'"
            )
        if self.board is not None:
            if self.plant != "hardware":
                raise ValueError("board is an option of plant 'hardware' only")
            split_endpoint("board", self.board)


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


@dataclass(frozen=True)
class NodeSpec:
    """One node of the graph.

    Attributes:
        package: ROS package that provides the executable.
        executable: Console script (``ros2 run <package> <executable>``).
        name: Node name (``-r __node:=<name>``).
        namespace: Node namespace without slashes (``-r __ns:=/<namespace>``).
        node_class: ``"module:Class"`` of the rclpy node, for composed mode.
        parameter_files: ROS 2 parameter files, lowest precedence first.
        parameters: Parameter overrides ``(name, value)``, applied after the files.
        remappings: Topic remappings ``(from, to)``.
        rt_priority: SCHED_FIFO priority of the process (1-99); 0: normal scheduling.
        hosts: Names of the nodes a process hosts when it hosts several (the direct loop): they keep their
            own names (no ``__node`` remapping), the parameter files apply to each by its name, and every
            node takes from :attr:`parameters` the names it declares.
    """

    package: str
    executable: str
    name: str
    node_class: str
    namespace: str = NAMESPACE
    parameter_files: tuple[str, ...] = ()
    parameters: tuple[tuple[str, ParameterValue], ...] = ()
    remappings: tuple[tuple[str, str], ...] = ()
    rt_priority: int = 0
    hosts: tuple[str, ...] = ()

    @property
    def fully_qualified_name(self) -> str:
        """Absolute node name, e.g. ``/smm/smm_sim_node``."""
        return f"/{self.namespace}/{self.name}" if self.namespace else f"/{self.name}"

    def ros_arguments(self) -> list[str]:
        """The ``--ros-args`` part of the command line (the same as ``ros2 launch`` would pass).

        Returns:
            ``["--ros-args", "-r", "__ns:=/smm", "-r", "__node:=<name>", "--params-file", F, ...,
            "-p", "key:=value", ..., "-r", "from:=to", ...]``.
        """
        namespace = f"/{self.namespace}" if self.namespace else "/"
        arguments = ["--ros-args", "-r", f"__ns:={namespace}"]
        if not self.hosts:
            arguments += ["-r", f"__node:={self.name}"]
        for path in self.parameter_files:
            arguments += ["--params-file", path]
        for name, value in self.parameters:
            arguments += ["-p", f"{name}:={format_parameter_value(value)}"]
        for source, target in self.remappings:
            arguments += ["-r", f"{source}:={target}"]
        return arguments

    def command_line(self, executable_path: str) -> list[str]:
        """Full argv to start this node as its own process.

        Args:
            executable_path: Resolved path of :attr:`executable`.
        """
        return [executable_path, *self.ros_arguments()]

    def load_class(self) -> type[Any]:
        """Import and return the node class (composed mode)."""
        module_name, _, class_name = self.node_class.partition(":")
        node_type: type[Any] = getattr(importlib.import_module(module_name), class_name)
        return node_type


def scenario_file(name: str) -> Path:
    """Path of the parameter file of scenario ``name`` (``smm_bringup/config/scenario_<name>.yaml``).

    Raises:
        ValueError: Unknown scenario.
        ParameterFileError: The file is missing.
    """
    if name not in SCENARIO_NAMES:
        raise ValueError(f"scenario must be one of {SCENARIO_NAMES}, got {name!r}")
    return package_file("smm_bringup", f"config/scenario_{name}.yaml")


def _sim_parameters(options: GraphOptions) -> tuple[tuple[str, ParameterValue], ...]:
    parameters: list[tuple[str, ParameterValue]] = [("clock_mode", options.clock_mode)]
    if options.duration is not None:
        parameters.append(("duration", float(options.duration)))
    elif options.clock_mode == "realtime" and options.scenario is not None:
        # A scenario file sets its length for lockstep runs; in real time the default is no end.
        parameters.append(("duration", 0.0))
    if options.seed is not None:
        parameters.append(("seed", options.seed))
    return tuple(parameters) + _period_parameters(options)


def _period_parameters(options: GraphOptions) -> tuple[tuple[str, ParameterValue], ...]:
    return () if options.control_period is None else (("control_period", float(options.control_period)),)


def _reference_parameters(files: Sequence[str]) -> tuple[tuple[str, ParameterValue], ...]:
    """The generator parameters the files set for ``reference_node``, renamed ``reference.<name>``.

    So the reference is configured in one place (the ``reference_node`` sections) wherever it is sampled.
    Only ``kind`` and ``<kind>.<field>`` are handed over, not the node's own settings (``lookahead``).
    """
    values: dict[str, Any] = {}
    for path in files:
        values.update(load_parameter_file(path, f"/{NAMESPACE}/{REFERENCE_NODE}"))
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
        PlantNotAvailableError: ``plant="hardware"`` with ``clock_mode="lockstep"``.
        ParameterFileError: A scenario or extra parameter file is missing.
    """
    if options.plant == "hardware" and options.clock_mode != "realtime":
        raise PlantNotAvailableError(
            "plant 'hardware' runs on the I/O board's own 1 kHz clock: use --clock-mode realtime"
        )
    files: list[str] = []
    if options.scenario is not None:
        files.append(str(scenario_file(options.scenario)))
    for extra in options.params_files:
        path = Path(extra)
        if not path.is_file():
            raise ParameterFileError(f"parameter file {extra} does not exist")
        files.append(str(path.resolve()))
    shared_files = tuple(files)
    plant_side: tuple[NodeSpec, ...] = (
        _hardware_specs(options, shared_files)
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
        recorder = (_recorder_spec(options),)
        if options.clock_mode == "lockstep" and options.plant == "sim":
            # Step 0 waits for the recorder (and every node reading joint_states) to be matched.
            readers = sum(spec.name in _JOINT_STATES_READERS for spec in controller_side) + (
                1 if fused else 0
            )
            gate = (("start.min_subscribers", readers + 1),)
            plant_side = tuple(
                dataclasses.replace(spec, parameters=spec.parameters + gate)
                if spec.name == SIM_NODE
                else spec
                for spec in plant_side
            )
    return tuple(_with_priority(spec, options) for spec in (*recorder, *plant_side, *controller_side))


def _with_priority(spec: NodeSpec, options: GraphOptions) -> NodeSpec:
    """``spec`` with the SCHED_FIFO priority ``options`` give its process (``GraphOptions.rt_priority``)."""
    priority = options.rt_priority
    if priority is None:
        priority = DEFAULT_HARDWARE_PRIORITY if options.plant == "hardware" else 0
    if priority and spec.name == EMULATOR_NODE:
        priority = min(MAX_PRIORITY, priority + BOARD_PRIORITY_OFFSET)
    elif priority and spec.name == HW_NODE:
        priority = min(MAX_PRIORITY, priority + BRIDGE_PRIORITY_OFFSET)
    elif priority and spec.name == RECORDER_NODE:
        priority = max(1, priority - RECORDER_PRIORITY_OFFSET)
    return dataclasses.replace(spec, rt_priority=priority)


def _hardware_specs(options: GraphOptions, files: Sequence[str]) -> tuple[NodeSpec, ...]:
    """``hw_bridge_node`` (autostart), after ``smm_bench_emulator`` unless a board address is given.

    The emulator gets the plant the parameter ``files`` give the simulator (noise, disturbance, inertias).
    """
    board = options.board or EMULATOR_BOARD
    address, port = split_endpoint("board", board)
    bind_address, bind_port = split_endpoint("host", EMULATOR_HOST)
    bridge_parameters: list[tuple[str, ParameterValue]] = [
        ("autostart", True),
        ("link.board_address", address),
        ("link.board_port", port),
    ]
    if options.board is None:
        bridge_parameters += [("link.bind_address", bind_address), ("link.bind_port", bind_port)]
    if options.control_period is not None:
        # The bridge's time limits are counted in board ticks at the default 1 kHz: scale them with the tick.
        period_ns = round(options.control_period * 1e9)
        bridge_parameters += [
            ("bridge.admission.period_ns", period_ns),
            ("bridge.admission.stale_ns", 20 * period_ns),
            ("bridge.host_watchdog_ns", 10 * period_ns),
            ("bridge.link_timeout_ns", 100 * period_ns),
        ]
    bridge = NodeSpec(
        package="smm_hw_bridge",
        executable=HW_NODE,
        name=HW_NODE,
        node_class="smm_hw_bridge.bridge_node:HwBridgeNode",
        parameters=tuple(bridge_parameters),
    )
    if options.loop == "direct":
        bridge = NodeSpec(
            package="smm_direct_loop",
            executable=DIRECT_LOOP,
            name=DIRECT_LOOP,
            node_class="",  # two nodes in one process, a thread of its own: a process, never composed
            parameter_files=tuple(files),
            parameters=(*bridge_parameters, *_controller_parameters(options, files)),
            hosts=(CONTROLLER_NODE, HW_NODE),
        )
    if options.board is not None:
        return (bridge,)
    emulator_parameters: list[tuple[str, ParameterValue]] = [("bind", board), ("host", EMULATOR_HOST)]
    if options.duration:
        emulator_parameters.append(("duration", float(options.duration)))
    if options.seed is not None:
        emulator_parameters.append(("seed", options.seed))
    if options.control_period is not None:
        emulator_parameters.append(("control-period", float(options.control_period)))
    emulator_parameters += _emulator_plant(files)
    emulator = NodeSpec(
        package="smm_bench_emulator",
        executable=EMULATOR_NODE,
        name=EMULATOR_NODE,
        node_class="",  # a plain process (the board side), not a ROS node: no composed mode
        parameters=tuple(emulator_parameters),
    )
    return (emulator, bridge)


def _emulator_plant(files: Sequence[str]) -> list[tuple[str, ParameterValue]]:
    """The emulator's plant options from the simulator's settings in the parameter ``files``.

    Raises:
        ParameterFileError: A per-joint noise the emulator cannot take (it takes one std for both joints).
    """
    sim: dict[str, Any] = {}
    for path in files:
        sim.update(load_parameter_file(path, f"/{NAMESPACE}/{SIM_NODE}"))
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


def expected_publishers(specs: Sequence[NodeSpec]) -> dict[str, int]:
    """Publishers a recorder must have matched per topic before the plant of ``specs`` starts stepping.

    Counts the controller-side nodes' stack topics (absolute names) and one ``/diagnostics`` publisher each.
    """
    counts: dict[str, int] = {}
    for spec in specs:
        if spec.name not in _PUBLISHED:
            continue
        published = _PUBLISHED[spec.name]
        if ("reference_source", "internal") in spec.parameters:
            published = (*published, topics.REFERENCE)
        for topic in (topics.fully_qualified(name, spec.namespace) for name in published):
            counts[topic] = counts.get(topic, 0) + 1
        counts["/diagnostics"] = counts.get("/diagnostics", 0) + max(1, len(spec.hosts))
    return counts


def _recorder_spec(options: GraphOptions) -> NodeSpec:
    """``recorder_node`` writing ``options.record``, with the run manifest's entries as parameters."""
    assert options.record is not None
    parameters: tuple[tuple[str, ParameterValue], ...] = (
        ("output", str(Path(options.record).resolve())),
        ("scenario", options.scenario or ""),
        ("seed", -1 if options.seed is None else options.seed),
        ("plant", options.plant),
        ("controller", options.algorithm),
        ("clock_mode", options.clock_mode),
        *_period_parameters(options),
    )
    return NodeSpec(
        package="smm_bag",
        executable=RECORDER_NODE,
        name=RECORDER_NODE,
        node_class="smm_bag.recorder_node:RecorderNode",
        parameters=parameters,
    )


# ------------------------------------------------------------------------------- composed mode support


def parameter_overrides(spec: NodeSpec) -> dict[str, Any]:
    """All parameter values the spec sets for its node, files first, then the explicit overrides.

    This is what the separate-process command line makes rcl compute; composed mode passes it to the
    node class as ``parameter_overrides``.
    """
    values: dict[str, Any] = {}
    for path in spec.parameter_files:
        values.update(load_parameter_file(path, spec.fully_qualified_name))
    for name, value in spec.parameters:
        values[name] = list(value) if isinstance(value, tuple) else value
    return values
