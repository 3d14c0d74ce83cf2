"""The graph description (smm_bringup.graph), smm-launch's command line, and the launch file."""

from __future__ import annotations

import dataclasses
import math
import os
import py_compile
import runpy
import shlex
import subprocess
import sys
import types
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import assume, given
from hypothesis import strategies as st
from smm_bringup.errors import ParameterFileError, PlantNotAvailableError
from smm_bringup.graph import build_graph, control_rate_file
from smm_bringup.graph_nodes import NodeSpec
from smm_bringup.graph_options import (
    CHAIN_LAYOUTS,
    CLOCK_MODES,
    CONTROL_RATES_HZ,
    LOOPS,
    PLANTS,
    REFERENCE_PLACEMENTS,
    SCENARIO_NAMES,
    GraphOptions,
    split_endpoint,
)
from smm_bringup.launcher import (
    arguments_from_options,
    options_from_arguments,
    run,
)
from smm_bringup.launcher import build_parser as launcher_parser
from smm_bringup.parameter_files import format_parameter_value, load_parameter_file
from smm_bringup.realtime import fifo, fifo_allowed
from smm_bringup.supervisor import EXIT_CONFIGURATION_ERROR, EXIT_OK
from smm_controller.laws import law_names

from smm_bringup import graph, graph_nodes, hardware_graph

REPO = Path(__file__).resolve().parents[2]
LAUNCH_DIR = REPO / "src" / "smm_bringup" / "launch"
FUSED_NODES = ["smm_sim_node", "controller_node"]
"""The default graph: the fused chain with the reference sampled inside controller_node."""
SPLIT_NODES = ["smm_sim_node", "td_node", "fleso_node", "reference_node", "controller_node"]


def test_default_graph_is_fused_in_namespace_smm() -> None:
    specs = build_graph(GraphOptions())
    assert [spec.name for spec in specs] == FUSED_NODES
    assert {spec.namespace for spec in specs} == {"smm"}
    assert [spec.package for spec in specs] == ["smm_sim", "smm_controller"]
    assert specs[0].fully_qualified_name == "/smm/smm_sim_node"
    assert dict(specs[-1].parameters)["chain"] == "internal"
    assert dict(specs[-1].parameters)["reference_source"] == "internal"


def test_split_graph_has_the_five_nodes_and_an_external_chain() -> None:
    specs = build_graph(GraphOptions(chain="split", reference="node"))
    assert [spec.name for spec in specs] == SPLIT_NODES
    assert [spec.package for spec in specs] == ["smm_sim"] + ["smm_controller"] * 4
    assert dict(specs[-1].parameters)["chain"] == "external"


@pytest.mark.parametrize("chain", ["fused", "split"])
def test_reference_in_the_controller_drops_reference_node_and_hands_over_its_parameters(
    tmp_path: Path, chain: str
) -> None:
    user = tmp_path / "user.yaml"
    user.write_text(
        "/**/reference_node:\n  ros__parameters:\n    lookahead: 2\n    sine:\n      amplitude: [0.5, 0.25]\n"
        "/**/controller_node:\n  ros__parameters:\n    pid:\n      kp: [1.0, 2.0]\n"
    )
    options = GraphOptions(chain=chain, reference="controller", scenario="case2", params_files=(str(user),))
    specs = build_graph(options)
    with_node = build_graph(
        GraphOptions(chain=chain, reference="node", scenario="case2", params_files=(str(user),))
    )
    assert [spec.name for spec in specs] == [spec.name for spec in with_node if spec.name != "reference_node"]
    controller = dict(specs[-1].parameters)
    assert controller["reference_source"] == "internal"
    # What reference_node would have been given (scenario file, then the user's file), renamed reference.*:
    given = graph_nodes.parameter_overrides(next(spec for spec in with_node if spec.name == "reference_node"))
    handed = {name.removeprefix("reference."): value for name, value in controller.items()}
    assert given.pop("lookahead") == 2  # a setting of reference_node itself: not handed over
    for name, value in given.items():
        assert handed[name] == (tuple(value) if isinstance(value, list) else value), name
    assert handed["kind"] == "sine" and handed["sine.amplitude"] == (0.5, 0.25)
    assert "lookahead" not in handed
    assert "reference_source" not in dict(with_node[-1].parameters)


def test_options_reach_the_right_nodes() -> None:
    specs = build_graph(
        GraphOptions(
            clock_mode="realtime", chain="split", reference="node", algorithm="npd", duration=2.5, seed=11
        )
    )
    by_name = {spec.name: dict(spec.parameters) for spec in specs}
    assert by_name["smm_sim_node"] == {
        "clock_mode": "realtime",
        "duration": 2.5,
        "seed": 11,
        "verdict.late_limit": 0.01,
    }
    assert by_name["controller_node"] == {"algorithm": "npd", "chain": "external"}
    assert by_name["td_node"] == {}


def test_the_control_rate_sets_the_period_of_every_node_and_the_simulator_integrates_at_1_ms() -> None:
    specs = build_graph(GraphOptions(control_rate=250, record="bag", chain="split", reference="node"))
    for spec in specs:
        assert dict(spec.parameters)["control_period"] == 0.004, spec.name
    sim = next(spec for spec in specs if spec.name == graph_nodes.SIM_NODE)
    assert dict(sim.parameters)["substeps"] == 4
    rate_file = str(control_rate_file(250))
    assert all(rate_file in spec.parameter_files for spec in specs if spec.name != graph_nodes.RECORDER_NODE)
    assert all("control_period" not in dict(spec.parameters) for spec in build_graph(GraphOptions()))
    assert control_rate_file(1000) is None  # 1 kHz: the configured defaults are its settings


def test_realtime_with_a_scenario_runs_without_end_unless_asked() -> None:
    sim = build_graph(GraphOptions(clock_mode="realtime", scenario="case1"))[0]
    assert dict(sim.parameters)["duration"] == 0.0
    lockstep = build_graph(GraphOptions(clock_mode="lockstep", scenario="case1"))[0]
    assert "duration" not in dict(lockstep.parameters)


def test_scenario_and_extra_files_are_passed_in_order(tmp_path: Path) -> None:
    extra = tmp_path / "extra.yaml"
    extra.write_text("/**:\n  ros__parameters:\n    seed: 1\n")
    specs = build_graph(GraphOptions(scenario="case2", params_files=(str(extra),)))
    for spec in specs:
        assert spec.parameter_files == (str(graph.scenario_file("case2")), str(extra.resolve()))


def test_missing_extra_file_is_a_graph_error(tmp_path: Path) -> None:
    with pytest.raises(ParameterFileError, match=r"nope\.yaml"):
        build_graph(GraphOptions(params_files=(str(tmp_path / "nope.yaml"),)))


def test_a_real_board_in_lockstep_is_refused_clearly() -> None:
    with pytest.raises(PlantNotAvailableError, match="realtime"):
        build_graph(GraphOptions(plant="hardware", clock_mode="lockstep", board="10.0.0.7:6000"))


def test_hardware_lockstep_clocks_the_emulator_by_the_controller_without_wall_clock_limits() -> None:
    specs = build_graph(
        GraphOptions(plant="hardware", clock_mode="lockstep", scenario="case2", start_timeout=7.0)
    )
    emulator, bridge = (dict(spec.parameters) for spec in specs[:2])
    assert (emulator["mode"], emulator["lockstep-trigger"]) == ("lockstep", "enabled")
    assert (emulator["start-timeout"], emulator["duration"]) == (7.0, 5.0)  # the scenario's length
    assert bridge["bridge.lockstep"] is True
    assert bridge["bridge.host_watchdog_ns"] >= 10_000_000_000  # type: ignore[operator]
    assert all(spec.rt_priority == 0 for spec in specs)  # lockstep needs no real-time scheduling
    realtime = dict(build_graph(GraphOptions(plant="hardware", clock_mode="realtime"))[0].parameters)
    assert "mode" not in realtime and realtime["duration-from"] == "live"  # a slow start shortens no run
    assert realtime["start-timeout"] == GraphOptions.start_timeout


def test_the_late_limit_reaches_the_emulator_and_the_bridge_as_their_units() -> None:
    specs = build_graph(GraphOptions(plant="hardware", clock_mode="realtime", late_limit=2.5))
    assert dict(specs[0].parameters)["late-limit"] == 2.5  # percent
    assert dict(specs[1].parameters)["verdict.late_limit"] == 0.025  # fraction


def test_the_late_limit_reaches_the_realtime_simulator_and_lockstep_is_not_judged() -> None:
    sim = build_graph(GraphOptions(clock_mode="realtime", late_limit=2.5))[0]
    assert (sim.name, dict(sim.parameters)["verdict.late_limit"]) == (graph_nodes.SIM_NODE, 0.025)
    lockstep = build_graph(GraphOptions(clock_mode="lockstep", late_limit=2.5))[0]
    assert "verdict.late_limit" not in dict(lockstep.parameters)


@pytest.mark.parametrize("layout", [{}, {"chain": "split", "reference": "node", "record": "bag"}])
def test_lockstep_simulator_runs_give_the_controller_side_sim_time(layout: dict[str, str]) -> None:
    """The simulator publishes /clock in lockstep; the nodes it drives take their time from it. The
    simulator (the clock's source) and the recorder (flushing and stamping on the wall clock) do not."""
    specs = build_graph(GraphOptions(clock_mode="lockstep", **layout))  # type: ignore[arg-type]
    keeping_wall_time = {graph_nodes.SIM_NODE, graph_nodes.RECORDER_NODE}
    for spec in specs:
        assert (dict(spec.parameters).get("use_sim_time") is True) == (spec.name not in keeping_wall_time)
        if spec.name not in keeping_wall_time:
            assert "-p" in spec.ros_arguments() and "use_sim_time:=true" in spec.ros_arguments()
    assert len(specs) > 1
    for options in (
        GraphOptions(clock_mode="realtime", **layout),  # type: ignore[arg-type]
        GraphOptions(plant="hardware", clock_mode="lockstep", **layout),  # type: ignore[arg-type]
    ):  # no /clock: wall time
        assert all("use_sim_time" not in dict(spec.parameters) for spec in build_graph(options))


@pytest.mark.parametrize(
    ("seed", "file_seed", "recorded"), [(None, None, 0), (None, 7, 7), (3, 7, 3), (0, None, 0)]
)
def test_the_recorder_is_told_the_seed_the_simulator_runs_with(
    tmp_path: Path, seed: int | None, file_seed: int | None, recorded: int
) -> None:
    """No --seed: the simulator's seed from the parameter files, else its default (0), not 'unknown'."""
    files: tuple[str, ...] = ()
    if file_seed is not None:
        extra = tmp_path / "seed.yaml"
        extra.write_text(f"/**/smm_sim_node:\n  ros__parameters:\n    seed: {file_seed}\n")
        files = (str(extra),)
    specs = build_graph(GraphOptions(record=str(tmp_path / "bag"), seed=seed, params_files=files))
    recorder = next(spec for spec in specs if spec.name == graph_nodes.RECORDER_NODE)
    assert dict(recorder.parameters)["seed"] == recorded


@pytest.mark.parametrize(
    ("seed", "bench_text", "recorded"),
    [
        (None, None, 0),  # the emulator's default
        (None, "plant: {seed: 7}\nseed: 7\n", 7),  # the bench file's
        (3, "plant: {seed: 7}\nseed: 7\n", 3),  # --seed replaces both
        (None, "plant: {seed: 7}\nseed: 8\n", -1),  # no single seed: unknown, not a wrong number
        (None, "[not, a, bench]\n", -1),  # the emulator refuses it (exit 2): no run
    ],
)
def test_the_recorder_is_told_the_seed_the_emulator_runs_with(
    tmp_path: Path, seed: int | None, bench_text: str | None, recorded: int
) -> None:
    """Hardware with the emulator: its --seed, else its bench file's, else its default (0)."""
    from smm_bench_emulator.cli import bench, from_ros_arguments
    from smm_bench_emulator.cli import build_parser as emulator_parser

    bench_file = None
    if bench_text is not None:
        bench_file = tmp_path / "bench.yaml"
        bench_file.write_text(bench_text)
    options = GraphOptions(
        plant="hardware",
        record=str(tmp_path / "bag"),
        seed=seed,
        bench_file=None if bench_file is None else str(bench_file),
    )
    specs = build_graph(options)
    recorder = next(spec for spec in specs if spec.name == graph_nodes.RECORDER_NODE)
    assert dict(recorder.parameters)["seed"] == recorded
    if recorded >= 0:  # the seeds the emulator then runs with (plant and A/D), from the options it gets
        emulator = next(spec for spec in specs if spec.name == graph_nodes.EMULATOR_NODE)
        board = bench(emulator_parser().parse_args(from_ros_arguments(list(emulator.ros_arguments()))))
        assert board.plant.seed == board.seed == recorded


def test_an_external_board_records_no_seed_and_refuses_one(tmp_path: Path) -> None:
    """A board's noise is its own: unknown (-1, ``smm.seed`` empty); a --seed it never gets is refused."""
    board = "192.168.1.20:50101"
    options = GraphOptions(plant="hardware", clock_mode="realtime", board=board, record=str(tmp_path / "b"))
    recorder = next(spec for spec in build_graph(options) if spec.name == graph_nodes.RECORDER_NODE)
    assert dict(recorder.parameters)["seed"] == -1
    with pytest.raises(ValueError, match=r"seed .* with board, there is none"):
        GraphOptions(plant="hardware", clock_mode="realtime", board=board, seed=5)


@pytest.mark.parametrize(
    ("name", "value"), [("late_limit", -1.0), ("late_limit", 101.0), ("start_timeout", 0.0)]
)
def test_bad_late_limit_or_start_timeout_is_rejected_with_its_name(name: str, value: float) -> None:
    with pytest.raises(ValueError, match=name):
        GraphOptions(plant="hardware", **{name: value})  # type: ignore[arg-type]


def test_hardware_plant_starts_the_emulator_then_the_bridge_then_the_same_controller_side() -> None:
    sim = build_graph(GraphOptions(clock_mode="realtime", scenario="case1", duration=3.0, seed=4))
    hardware = build_graph(
        GraphOptions(plant="hw", clock_mode="realtime", scenario="case1", duration=3.0, seed=4, loop="topics")
    )
    assert [spec.name for spec in hardware] == [
        graph_nodes.EMULATOR_NODE,
        graph_nodes.HW_NODE,
        *[s.name for s in sim[1:]],
    ]
    # Nothing changes on the controller side but its scheduling (SCHED_FIFO 50 on the bench; the bridge 55).
    assert [dataclasses.replace(spec, rt_priority=0) for spec in hardware[2:]] == list(sim[1:])
    assert [spec.rt_priority for spec in hardware] == [70, 55, *[50] * len(sim[1:])]
    assert {spec.rt_priority for spec in sim} == {0}
    emulator, bridge = dict(hardware[0].parameters), dict(hardware[1].parameters)
    assert emulator == {
        "bind": hardware_graph.EMULATOR_BOARD,
        "host": hardware_graph.EMULATOR_HOST,
        "late-limit": 1.0,
        "duration": 3.0,
        "start-timeout": 60.0,
        "duration-from": "live",
        "seed": 4,
        "noise-std": 0.0,  # case1's plant, as the simulator would run it
        "inertia-scale": 1.0,
        "disturbance": "none",
    }
    assert (
        bridge["autostart"] is True
        and bridge["link.board_port"] == 50101
        and bridge["link.bind_port"] == 50100
    )
    assert hardware[0].name in graph_nodes.PLANT_NODE_NAMES  # the emulator's end is the end of the run
    slow = build_graph(GraphOptions(plant="hardware", clock_mode="realtime", control_rate=500))
    emulator, bridge = dict(slow[0].parameters), dict(slow[1].parameters)
    assert "control-period" not in emulator  # the board keeps its 1 kHz tick
    assert emulator["control-divider"] == 2 and bridge["bridge.control_divider"] == 2
    assert "bridge.admission.period_ns" not in bridge


def test_the_emulator_runs_the_scenario_plant_the_simulator_would(tmp_path: Path) -> None:
    specs = build_graph(GraphOptions(plant="hardware", clock_mode="realtime", scenario="case2"))
    emulator = dict(specs[0].parameters)
    assert (emulator["noise-std"], emulator["inertia-scale"], emulator["disturbance"]) == (0.001, 1.1, "eq46")
    extra = tmp_path / "noise.yaml"
    extra.write_text("/**/smm_sim_node:\n  ros__parameters:\n    noise_std: [0.002, 0.002]\n")
    specs = build_graph(
        GraphOptions(plant="hardware", clock_mode="realtime", scenario="case2", params_files=(str(extra),))
    )
    assert dict(specs[0].parameters)["noise-std"] == 0.002  # a later file wins, as for the simulator
    extra.write_text("/**/smm_sim_node:\n  ros__parameters:\n    noise_std: [0.002, 0.001]\n")
    with pytest.raises(ParameterFileError, match=r"noise_std.*one noise std"):
        build_graph(GraphOptions(plant="hardware", clock_mode="realtime", params_files=(str(extra),)))


def test_the_emulator_accepts_every_option_the_graph_passes_it() -> None:
    from smm_bench_emulator.cli import bench, from_ros_arguments
    from smm_bench_emulator.cli import build_parser as emulator_parser

    options = GraphOptions(
        plant="hardware", clock_mode="realtime", scenario="case2", seed=3, control_rate=250
    )
    spec = build_graph(options)[0]
    assert spec.name == graph_nodes.EMULATOR_NODE
    parsed = emulator_parser().parse_args(from_ros_arguments([spec.executable, *spec.ros_arguments()][1:]))
    assert (parsed.noise_std, parsed.inertia_scale, parsed.disturbance) == (0.001, 1.1, "eq46")
    assert (parsed.seed, bench(parsed).plant.control_period, parsed.control_divider) == (3, 0.001, 4)
    assert parsed.bind == split_endpoint("board", hardware_graph.EMULATOR_BOARD)
    with pytest.raises(ValueError, match="unknown parameter 'valve'"):
        from_ros_arguments(["--ros-args", "-p", "valve:=1"])


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (
            GraphOptions(clock_mode="realtime", rt_priority=10),
            {graph_nodes.SIM_NODE: 10, graph_nodes.CONTROLLER_NODE: 10},
        ),
        (
            GraphOptions(plant="hardware", clock_mode="realtime", rt_priority=0, loop="topics"),
            {graph_nodes.EMULATOR_NODE: 0, graph_nodes.HW_NODE: 0, graph_nodes.CONTROLLER_NODE: 0},
        ),
        (
            GraphOptions(
                plant="hardware", clock_mode="realtime", rt_priority=90, record="bag", loop="topics"
            ),
            {
                graph_nodes.RECORDER_NODE: 80,
                graph_nodes.EMULATOR_NODE: 99,
                graph_nodes.HW_NODE: 95,
                graph_nodes.CONTROLLER_NODE: 90,
            },
        ),
        (
            GraphOptions(clock_mode="realtime", rt_priority=5, record="bag"),
            {graph_nodes.RECORDER_NODE: 1, graph_nodes.SIM_NODE: 5, graph_nodes.CONTROLLER_NODE: 5},
        ),
    ],
)
def test_rt_priority_goes_to_the_loop_processes_and_the_board_runs_above(
    options: GraphOptions, expected: dict[str, int]
) -> None:
    assert {spec.name: spec.rt_priority for spec in build_graph(options)} == expected


@pytest.mark.parametrize("bad", [-1, 99, 1.5, True, "50"])
def test_invalid_rt_priority_is_refused_with_its_name(bad: Any) -> None:
    with pytest.raises(ValueError, match="rt_priority"):
        GraphOptions(rt_priority=bad)


def test_children_run_under_sched_fifo_when_the_system_allows_it(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from smm_bringup import supervisor

    probe = "import os; print(os.sched_getscheduler(0), os.sched_getparam(0).sched_priority, end='')"
    spec = NodeSpec("p", "python", "probe", "", rt_priority=7)
    allowed = fifo_allowed(7)
    schedulings = supervisor._schedulings([spec, NodeSpec("p", "python", "other", "")])
    policy = subprocess.run(
        [sys.executable, "-c", probe],
        preexec_fn=schedulings["probe"].preexec() if schedulings else None,  # as GraphProcesses starts it
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    if allowed:
        assert schedulings == {"probe": fifo(7)}
        assert policy == f"{os.SCHED_FIFO} 7"
    else:  # e.g. a container without CAP_SYS_NICE: said once, then normal scheduling
        assert schedulings == {}
        assert "cannot use SCHED_FIFO" in capsys.readouterr().err
        assert policy == f"{os.SCHED_OTHER} 0"
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the probe left the launcher as it was


def test_hardware_plant_with_a_board_address_starts_no_emulator() -> None:
    specs = build_graph(
        GraphOptions(plant="hardware", clock_mode="realtime", board="10.0.0.7:6000", loop="topics")
    )
    assert specs[0].name == graph_nodes.HW_NODE
    parameters = dict(specs[0].parameters)
    assert (parameters["link.board_address"], parameters["link.board_port"]) == ("10.0.0.7", 6000)
    assert "link.bind_address" not in parameters  # the bridge keeps its configured (loopback) bind address
    for bad in ("10.0.0.7", "bench:6000", "10.0.0.7:0"):
        with pytest.raises(ValueError, match="board"):
            GraphOptions(plant="hardware", clock_mode="realtime", board=bad)
    with pytest.raises(ValueError, match="board"):
        GraphOptions(board="10.0.0.7:6000")


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"plant": "mars"}, "plant"),
        ({"clock_mode": "slow"}, "clock_mode"),
        ({"chain": "tangled"}, "chain"),
        ({"reference": "oracle"}, "reference"),
        ({"algorithm": "lqr"}, "algorithm"),
        ({"scenario": "case9"}, "scenario"),
        ({"duration": -1.0}, "duration"),
        ({"seed": -2}, "seed"),
        ({"control_rate": 300}, "control rate must be one of 1000, 500, 250, 200, 100 Hz"),
        ({"control_rate": 0}, "control rate"),
        ({"control_rate": math.nan}, "control rate"),
        ({"control_rate": True}, "control rate"),
    ],
)
def test_invalid_options_name_the_field(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        GraphOptions(**changes)


def test_ros_arguments_are_those_of_ros2_launch() -> None:
    spec = NodeSpec(
        "smm_sim",
        "smm_sim_node",
        "sim",
        "smm_sim.sim_node:SimNode",
        parameter_files=("/a.yaml",),
        parameters=(("duration", 5.0), ("clock_mode", "lockstep"), ("noise_std", (0.001, 0.002))),
        remappings=(("joint_states", "raw"),),
    )
    assert spec.ros_arguments() == [
        "--ros-args",
        "-r",
        "__ns:=/smm",
        "-r",
        "__node:=sim",
        "--params-file",
        "/a.yaml",
        "-p",
        "duration:=5.0",
        "-p",
        'clock_mode:="lockstep"',
        "-p",
        "noise_std:=[0.001, 0.002]",
        "-r",
        "joint_states:=raw",
    ]


@pytest.mark.parametrize(
    "value",
    [True, False, 0, 7, -3, 1.0, 0.001, 5e-9, "lockstep", "1", "true", "", (1.0, 2.5), (1, 2), ("a", "b")],
)
def test_parameter_values_survive_the_yaml_round_trip_with_their_type(value: Any) -> None:
    parsed = yaml.safe_load(format_parameter_value(value))
    expected = list(value) if isinstance(value, tuple) else value
    assert parsed == expected
    assert type(parsed) is type(expected)
    if isinstance(value, tuple):
        assert [type(item) for item in parsed] == [type(item) for item in value]


@pytest.mark.parametrize("value", [float("inf"), float("nan"), None, 1j])
def test_unrepresentable_parameter_values_are_refused(value: Any) -> None:
    with pytest.raises(ValueError):
        format_parameter_value(value)


def test_parameter_file_sections_apply_with_wildcards_first(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text(
        "/smm/smm_sim_node:\n  ros__parameters:\n    seed: 3\n"
        "/**:\n  ros__parameters:\n    seed: 1\n    duration: 2.0\n    nested:\n      a: [1.0, 2.0]\n"
        "/**/td_node:\n  ros__parameters:\n    seed: 9\n"
    )
    assert load_parameter_file(path, "/smm/smm_sim_node") == {
        "seed": 3,
        "duration": 2.0,
        "nested.a": [1.0, 2.0],
    }
    assert load_parameter_file(path, "/smm/td_node")["seed"] == 9


@pytest.mark.parametrize("content", ["- 1\n- 2\n", "/**:\n  params:\n    a: 1\n", "a: [1,\n"])
def test_invalid_parameter_files_are_refused(tmp_path: Path, content: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    with pytest.raises(ParameterFileError):
        load_parameter_file(path, "/smm/smm_sim_node")


def test_parameter_overrides_put_explicit_values_after_files(tmp_path: Path) -> None:
    path = tmp_path / "p.yaml"
    path.write_text("/**:\n  ros__parameters:\n    seed: 1\n    duration: 2.0\n")
    spec = NodeSpec("p", "e", "smm_sim_node", "m:C", parameter_files=(str(path),), parameters=(("seed", 5),))
    assert graph_nodes.parameter_overrides(spec) == {"seed": 5, "duration": 2.0}


def test_launcher_arguments_map_onto_graph_options() -> None:
    arguments = launcher_parser().parse_args(
        [
            "--clock-mode",
            "realtime",
            "--chain",
            "split",
            "--reference",
            "controller",
            "--algorithm",
            "pid",
            "--scenario",
            "none",
            "--duration",
            "3",
            "--seed",
            "4",
            "--control-rate",
            "500",
        ]
    )
    assert options_from_arguments(arguments) == GraphOptions(
        clock_mode="realtime",
        chain="split",
        reference="controller",
        algorithm="pid",
        scenario=None,
        duration=3.0,
        seed=4,
        control_rate=500,
    )


@st.composite
def graph_options(draw: st.DrawFn) -> GraphOptions:
    """Any valid GraphOptions."""
    positive = st.floats(min_value=1e-4, max_value=1e4, allow_nan=False, allow_infinity=False)
    try:
        return GraphOptions(
            plant=draw(st.sampled_from(PLANTS)),
            clock_mode=draw(st.sampled_from(CLOCK_MODES)),
            chain=draw(st.sampled_from(CHAIN_LAYOUTS)),
            reference=draw(st.sampled_from(REFERENCE_PLACEMENTS)),
            algorithm=draw(st.sampled_from(law_names())),
            scenario=draw(st.none() | st.sampled_from(SCENARIO_NAMES)),
            duration=draw(st.none() | st.just(0.0) | positive),
            seed=draw(st.none() | st.integers(min_value=0, max_value=2**32 - 1)),
            params_files=tuple(draw(st.lists(st.sampled_from(["a.yaml", "dir/b c.yaml"]), max_size=3))),
            control_rate=draw(st.sampled_from(CONTROL_RATES_HZ)),
            board=draw(st.none() | st.just("192.168.0.9:50101")),
            record=draw(st.none() | st.just("bags/run 1")),
            rt_priority=draw(st.none() | st.integers(min_value=0, max_value=98)),
            loop=draw(st.sampled_from(LOOPS)),
            late_limit=draw(st.floats(min_value=0.0, max_value=100.0)),
            start_timeout=draw(positive),
        )
    except ValueError:
        assume(False)
        raise


@given(graph_options())
def test_launcher_arguments_from_options_give_the_same_options_back(options: GraphOptions) -> None:
    arguments = launcher_parser().parse_args(arguments_from_options(options))
    assert options_from_arguments(arguments) == options


def test_launcher_reports_hardware_in_lockstep_and_composed_and_exits_2(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert run(["--plant", "hardware", "--board", "10.0.0.7:6000"]) == EXIT_CONFIGURATION_ERROR
    assert "realtime" in capsys.readouterr().err
    assert run(["--plant", "hardware", "--clock-mode", "realtime", "--composed"]) == EXIT_CONFIGURATION_ERROR
    assert "smm_bench_emulator" in capsys.readouterr().err


def test_launcher_reports_bad_values_and_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["--duration", "-1"]) == EXIT_CONFIGURATION_ERROR
    assert "duration" in capsys.readouterr().err


def test_dry_run_prints_the_command_lines(capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["--dry-run", "--seed", "3"]) == EXIT_OK
    commands = [shlex.split(line) for line in capsys.readouterr().out.splitlines()]
    assert [Path(command[0]).name for command in commands] == FUSED_NODES
    assert all(Path(command[0]).is_absolute() and Path(command[0]).is_file() for command in commands)
    assert "seed:=3" in commands[0]
    # an array value is one word once the shell has split the line, as rcl needs it
    assert "reference.sine.amplitude:=[1.0, 0.785]" in commands[1]


# ------------------------------------------------------------------------------------------- launch file


def test_launch_files_compile() -> None:
    files = sorted(LAUNCH_DIR.glob("*.launch.py"))
    assert files
    for path in files:
        py_compile.compile(str(path), doraise=True)


class _Recorded:
    """Stand-in for a launch / launch_ros class: remembers its constructor arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args = args
        self.kwargs = kwargs


def _fake_launch_modules() -> dict[str, types.ModuleType]:
    modules = {
        name: types.ModuleType(name)
        for name in (
            "launch",
            "launch.actions",
            "launch.events",
            "launch.substitutions",
            "launch_ros",
            "launch_ros.actions",
        )
    }
    classes = {
        "launch": ["LaunchDescription"],
        "launch.actions": ["DeclareLaunchArgument", "EmitEvent", "LogInfo", "OpaqueFunction"],
        "launch.events": ["Shutdown"],
        "launch.substitutions": ["LaunchConfiguration"],
        "launch_ros.actions": ["Node"],
    }
    for module, names in classes.items():
        for name in names:
            setattr(modules[module], name, type(name, (_Recorded,), {}))
    return modules


class _FakeContext:
    def __init__(self, values: dict[str, str]) -> None:
        self.values = values

    def perform_substitution(self, substitution: Any) -> str:
        return self.values[substitution.args[0]]


def _launched_nodes(monkeypatch: pytest.MonkeyPatch, arguments: dict[str, str]) -> list[Any]:
    for name, module in _fake_launch_modules().items():
        monkeypatch.setitem(sys.modules, name, module)
    namespace = runpy.run_path(str(LAUNCH_DIR / "smm.launch.py"))
    description = namespace["generate_launch_description"]()
    entities = description.args[0]
    defaults = {
        e.kwargs.get("name", e.args[0] if e.args else None): e.kwargs["default_value"]
        for e in entities
        if type(e).__name__ == "DeclareLaunchArgument"
    }
    opaque = [e for e in entities if type(e).__name__ == "OpaqueFunction"]
    assert len(opaque) == 1
    values = {**defaults, **arguments}
    return list(opaque[0].kwargs["function"](_FakeContext(values)))


@pytest.mark.parametrize(
    ("arguments", "options"),
    [
        ({}, GraphOptions()),
        (
            {
                "clock_mode": "realtime",
                "chain": "split",
                "reference": "controller",
                "algorithm": "fpd",
                "scenario": "case1",
                "duration": "2",
                "seed": "5",
                "control_rate": "500",
            },
            GraphOptions(
                clock_mode="realtime",
                chain="split",
                reference="controller",
                algorithm="fpd",
                scenario="case1",
                duration=2.0,
                seed=5,
                control_rate=500,
            ),
        ),
        ({"scenario": "none"}, GraphOptions(scenario=None)),
    ],
)
def test_launch_file_starts_the_graph_the_launcher_starts(
    monkeypatch: pytest.MonkeyPatch, arguments: dict[str, str], options: GraphOptions
) -> None:
    nodes = _launched_nodes(monkeypatch, arguments)
    specs = build_graph(options)
    assert [node.kwargs["name"] for node in nodes] == [spec.name for spec in specs]
    for node, spec in zip(nodes, specs, strict=True):
        assert node.kwargs["package"] == spec.package
        assert node.kwargs["executable"] == spec.executable
        assert node.kwargs["namespace"] == spec.namespace
        *files, overrides = node.kwargs["parameters"]
        assert tuple(files) == spec.parameter_files
        assert overrides == {k: list(v) if isinstance(v, tuple) else v for k, v in spec.parameters}
        assert [type(action).__name__ for action in node.kwargs["on_exit"]] == ["LogInfo", "EmitEvent"]


def test_launch_file_starts_the_hardware_graph(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(PlantNotAvailableError):
        _launched_nodes(monkeypatch, {"plant": "hardware", "board": "10.0.0.7:6000"})
    arguments = {"plant": "hardware", "clock_mode": "realtime", "duration": "2", "loop": "topics"}
    nodes = _launched_nodes(monkeypatch, arguments)
    specs = build_graph(GraphOptions(plant="hardware", clock_mode="realtime", duration=2.0, loop="topics"))
    assert [node.kwargs["name"] for node in nodes] == [spec.name for spec in specs]
    emulator = nodes[0].kwargs
    assert "parameters" not in emulator  # a plain process: options on its command line
    assert emulator["arguments"] == [
        "--bind",
        hardware_graph.EMULATOR_BOARD,
        "--host",
        hardware_graph.EMULATOR_HOST,
        "--late-limit",
        "1.0",
        "--duration",
        "2.0",
        "--start-timeout",
        "60.0",
        "--duration-from",
        "live",
        "--noise-std",  # the default scenario's (case2) plant
        "0.001",
        "--inertia-scale",
        "1.1",
        "--disturbance",
        "eq46",
    ]
    nodes = _launched_nodes(
        monkeypatch, {"plant": "hardware", "clock_mode": "realtime", "board": "192.168.1.20:50101"}
    )
    assert nodes[0].kwargs["executable"] == graph_nodes.DIRECT_LOOP  # hardware's default loop in real time


def test_launch_file_records_and_sets_real_time_priorities(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    bag = str(tmp_path / "run")
    arguments = {"plant": "hardware", "clock_mode": "realtime", "record": bag, "loop": "topics"}
    specs = build_graph(GraphOptions(plant="hardware", clock_mode="realtime", record=bag, loop="topics"))
    nodes = _launched_nodes(monkeypatch, arguments)
    assert [node.kwargs["name"] for node in nodes] == [spec.name for spec in specs]
    assert nodes[0].kwargs["name"] == graph_nodes.RECORDER_NODE
    prefixes = {node.kwargs["name"]: node.kwargs["prefix"] for node in nodes}
    assert prefixes == {
        graph_nodes.RECORDER_NODE: "chrt -f 40",
        graph_nodes.EMULATOR_NODE: "chrt -f 70",
        graph_nodes.HW_NODE: "chrt -f 55",
        graph_nodes.CONTROLLER_NODE: "chrt -f 50",
    }
    nodes = _launched_nodes(monkeypatch, {**arguments, "rt_priority": "0"})
    assert {node.kwargs["prefix"] for node in nodes} == {None}


# ------------------------------------------------------------------------------------ console scripts


def test_every_node_executable_is_installed() -> None:
    from smm_bringup.supervisor import resolve_executable

    for spec in build_graph(GraphOptions(scenario=None)):
        assert Path(resolve_executable(spec)).is_file(), spec.executable


@pytest.mark.ros
def test_rcl_parses_the_command_line_parameters_with_their_types(ros_context: Any) -> None:
    import rclpy

    spec = NodeSpec(
        "p",
        "e",
        "probe",
        "m:C",
        parameters=(
            ("duration", 5.0),
            ("seed", 3),
            ("clock_mode", "lockstep"),
            ("noise_std", (0.001, 0.0)),
            ("flag", True),
            ("label", "1"),
        ),
    )
    node = rclpy.create_node(
        "placeholder",
        context=ros_context,
        cli_args=spec.ros_arguments(),
        use_global_arguments=False,
        automatically_declare_parameters_from_overrides=True,
    )
    try:
        assert node.get_fully_qualified_name() == "/smm/probe"
        values = {
            name: node.get_parameter(name).value
            for name in ("duration", "seed", "clock_mode", "flag", "label")
        }
        assert values == {"duration": 5.0, "seed": 3, "clock_mode": "lockstep", "flag": True, "label": "1"}
        assert type(values["duration"]) is float and type(values["seed"]) is int
        assert list(node.get_parameter("noise_std").value) == [0.001, 0.0]
    finally:
        node.destroy_node()


@pytest.mark.parametrize("name", SCENARIO_NAMES)
def test_scenario_files_agree_with_smm_analysis(name: str) -> None:
    import numpy as np
    from smm_analysis.scenarios import get_scenario
    from smm_controller.reference import make_reference

    scenario = get_scenario(name)
    path = graph.scenario_file(name)
    sim = load_parameter_file(path, "/smm/smm_sim_node")
    assert sim == {
        "noise_std": list(scenario.noise_std),
        "disturbance": scenario.disturbance,
        "inertia_scale": scenario.inertia_scale,
        "duration": scenario.duration,
    }
    assert all(type(value) is float for value in (sim["inertia_scale"], sim["duration"], *sim["noise_std"]))
    reference = load_parameter_file(path, "/smm/reference_node")
    kind = reference.pop("kind")
    assert kind == scenario.reference_kind
    fields = {key.split(".", 1)[1]: value for key, value in reference.items() if key.startswith(f"{kind}.")}
    assert len(fields) == len(reference), "parameters of another reference kind in the file"
    times = np.linspace(0.0, scenario.duration, 501)
    expected = scenario.reference().sample(times)
    np.testing.assert_array_equal(make_reference(kind, **fields).sample(times), expected)
    assert load_parameter_file(path, "/smm/td_node") == {}


def test_a_missing_executable_is_reported_before_anything_starts() -> None:
    from smm_bringup.supervisor import ExecutableNotFoundError, launch_processes, resolve_executable

    missing = NodeSpec("smm_sim", "no_such_node", "ghost", "m:C")
    with pytest.raises(ExecutableNotFoundError, match="no_such_node"):
        resolve_executable(missing)
    real = build_graph(GraphOptions(scenario=None))[0]
    with pytest.raises(ExecutableNotFoundError):
        launch_processes([real, missing])


@pytest.mark.parametrize(("loop", "readers"), [("topics", 2), ("direct", 1)])
def test_a_recorded_hardware_run_arms_once_the_recorder_reads_joint_states(loop: str, readers: int) -> None:
    specs = build_graph(GraphOptions(plant="hardware", clock_mode="lockstep", loop=loop, record="bag"))
    bridge = dict(specs[-1 if loop == "direct" else 2].parameters)  # recorder, emulator, bridge, controller
    assert bridge["autostart_subscribers"] == readers  # the recorder (+ controller_node in the topics loop)
    assert all(
        "autostart_subscribers" not in dict(spec.parameters)
        for spec in build_graph(GraphOptions(plant="hardware", clock_mode="lockstep", loop=loop))
    )
