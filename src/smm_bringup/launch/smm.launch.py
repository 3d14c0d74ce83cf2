"""Start the SMM control graph on a ROS 2 Jazzy install: ``ros2 launch smm_bringup smm.launch.py``.

The node list comes from :func:`smm_bringup.graph.build_graph`, as for ``smm-launch``, so the two cannot
drift apart. Arguments (``plant``, ``board``, ``clock_mode``, ``algorithm``, ``scenario``, ``loop``,
``chain``, ``reference``, ``duration``, ``seed``, ``params_file``, ``control_rate``, ``record``,
``rt_priority``) and how the launch ends: docs/LAUNCH.md, "On a ROS 2 Jazzy machine".
"""

from __future__ import annotations

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, LogInfo, OpaqueFunction
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import NodeSpec
from smm_bringup.graph_options import (
    CHAIN_LAYOUTS,
    CLOCK_MODES,
    LOOPS,
    PLANTS,
    REFERENCE_PLACEMENTS,
    SCENARIO_NAMES,
    GraphOptions,
)
from smm_controller.laws import law_names

ARGUMENTS = (
    ("plant", "sim", f"plant node: {' | '.join(PLANTS)}"),
    ("clock_mode", "lockstep", f"simulator clock: {' | '.join(CLOCK_MODES)}"),
    ("loop", "auto", f"control loop: {' | '.join(LOOPS)}"),
    ("chain", "fused", f"chain layout: {' | '.join(CHAIN_LAYOUTS)}"),
    ("reference", "controller", f"who samples the reference: {' | '.join(REFERENCE_PLACEMENTS)}"),
    ("algorithm", "fpdeso", f"controller: {' | '.join(law_names())}"),
    ("scenario", "case2", f"scenario: {' | '.join(SCENARIO_NAMES)} | none"),
    ("duration", "", "simulated seconds until the simulator stops (empty: scenario / endless; 0: endless)"),
    ("seed", "", "noise seed of the simulator (empty: as configured)"),
    ("params_file", "", "extra ROS 2 parameter file for every node (empty: none)"),
    (
        "control_rate",
        "1000",
        "control rate, Hz: 1000 | 500 | 250 | 200 | 100 (the board's 1 kHz tick divided by N)",
    ),
    ("board", "", "plant hardware: ADDRESS:PORT of the I/O board (empty: start the bench emulator)"),
    ("record", "", "bag folder to record every topic to (empty: no recording)"),
    ("rt_priority", "", "SCHED_FIFO priority of the loop's processes (empty: 50 with hardware, else 0)"),
)


def options_from_launch_arguments(values: dict[str, str]) -> GraphOptions:
    """Turn the launch arguments (strings) into the graph options smm-launch uses too."""
    scenario = values["scenario"]
    return GraphOptions(
        plant=values["plant"],  # type: ignore[arg-type]
        clock_mode=values["clock_mode"],  # type: ignore[arg-type]
        chain=values["chain"],  # type: ignore[arg-type]
        reference=values["reference"],  # type: ignore[arg-type]
        algorithm=values["algorithm"],
        scenario=None if scenario == "none" else scenario,
        duration=float(values["duration"]) if values["duration"] else None,
        seed=int(values["seed"]) if values["seed"] else None,
        params_files=(values["params_file"],) if values["params_file"] else (),
        control_rate=float(values["control_rate"]),
        board=values["board"] or None,
        record=values["record"] or None,
        rt_priority=int(values["rt_priority"]) if values["rt_priority"] else None,
        loop=values["loop"],  # type: ignore[arg-type]
    )


def node_action(spec: NodeSpec) -> Node:
    """One launch_ros Node for one spec of the graph (files first, then the explicit overrides)."""
    overrides = {name: list(value) if isinstance(value, tuple) else value for name, value in spec.parameters}
    prefix = f"chrt -f {spec.rt_priority}" if spec.rt_priority else None
    if spec.hosts:  # several nodes in one process (the direct loop): each keeps its name
        return Node(
            package=spec.package,
            executable=spec.executable,
            namespace=spec.namespace,
            parameters=[*spec.parameter_files, overrides],
            output="screen",
            prefix=prefix,
            on_exit=[
                LogInfo(msg=f"{spec.name} exited; stopping the graph"),
                EmitEvent(event=Shutdown(reason=f"{spec.name} exited")),
            ],
        )
    if not spec.node_class:  # a plain process (the bench emulator): its settings are command-line options
        return Node(
            package=spec.package,
            executable=spec.executable,
            name=spec.name,
            namespace=spec.namespace,
            arguments=[text for name, value in spec.parameters for text in (f"--{name}", str(value))],
            output="screen",
            prefix=prefix,
            on_exit=[
                LogInfo(msg=f"{spec.name} exited; stopping the graph"),
                EmitEvent(event=Shutdown(reason=f"{spec.name} exited")),
            ],
        )
    return Node(
        package=spec.package,
        executable=spec.executable,
        name=spec.name,
        namespace=spec.namespace,
        parameters=[*spec.parameter_files, overrides],
        remappings=list(spec.remappings),
        output="screen",
        prefix=prefix,
        on_exit=[
            LogInfo(msg=f"{spec.name} exited; stopping the graph"),
            EmitEvent(event=Shutdown(reason=f"{spec.name} exited")),
        ],
    )


def _nodes(context, *_args, **_kwargs):  # type: ignore[no-untyped-def]
    values = {name: context.perform_substitution(_configuration(name)) for name, _, _ in ARGUMENTS}
    return [node_action(spec) for spec in build_graph(options_from_launch_arguments(values))]


def _configuration(name: str) -> LaunchConfiguration:
    return LaunchConfiguration(name)


def generate_launch_description() -> LaunchDescription:
    """The launch description: the arguments, then the graph built from them."""
    return LaunchDescription(
        [
            DeclareLaunchArgument(name, default_value=default, description=text)
            for name, default, text in ARGUMENTS
        ]
        + [OpaqueFunction(function=_nodes)]
    )
