"""Which loop a hardware run gets by default, and the preflight's options on the way to the bridge."""

from __future__ import annotations

from typing import Any

import pytest
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import DIRECT_LOOP, HW_NODE
from smm_bringup.graph_options import GraphOptions
from smm_bringup.launcher import arguments_from_options, build_parser, options_from_arguments, run


def test_hardware_in_real_time_gets_the_direct_loop_by_default() -> None:
    options = GraphOptions(plant="hardware", clock_mode="realtime")
    assert options.loop == "direct" and options.loop_note is None
    assert [spec.name for spec in build_graph(options)][-1] == DIRECT_LOOP


@pytest.mark.parametrize(
    ("choice", "named"), [({"chain": "split"}, "--chain split"), ({"reference": "node"}, "--reference node")]
)
def test_a_choice_the_direct_loop_cannot_host_falls_back_to_topics_and_says_so(
    choice: dict[str, Any], named: str
) -> None:
    options = GraphOptions(plant="hardware", clock_mode="realtime", **choice)
    assert options.loop == "topics"
    assert options.loop_note == f"the direct loop cannot host {named}: using the topics loop"
    assert HW_NODE in [spec.name for spec in build_graph(options)]


def test_both_unhosted_choices_are_named_in_one_line() -> None:
    options = GraphOptions(plant="hardware", clock_mode="realtime", chain="split", reference="node")
    assert options.loop_note == (
        "the direct loop cannot host --chain split --reference node: using the topics loop"
    )


@pytest.mark.parametrize(
    "options",
    [
        GraphOptions(plant="hardware", clock_mode="lockstep"),
        GraphOptions(clock_mode="realtime"),
        GraphOptions(),
        GraphOptions(plant="hardware", clock_mode="realtime", loop="topics"),
    ],
)
def test_lockstep_the_simulator_and_an_explicit_choice_keep_the_topics_loop(options: GraphOptions) -> None:
    assert options.loop == "topics" and options.loop_note is None


def test_an_explicit_direct_loop_with_a_split_chain_is_still_refused() -> None:
    with pytest.raises(ValueError, match="loop 'direct'"):
        GraphOptions(plant="hardware", clock_mode="realtime", loop="direct", chain="split")


def test_smm_launch_says_in_one_line_that_it_uses_the_topics_loop(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["--plant", "hardware", "--clock-mode", "realtime", "--reference", "node", "--dry-run"]
    assert run(argv) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "[smm-launch] the direct loop cannot host --reference node: using the topics loop"
    assert any(line.split()[0].endswith(HW_NODE) for line in out[1:])


def test_preflight_options_reach_the_bridge_and_survive_the_round_trip() -> None:
    options = GraphOptions(plant="hardware", clock_mode="realtime", preflight=1.5, force=True)
    bridge = dict(build_graph(options)[-1].parameters)
    assert bridge["preflight.duration_s"] == 1.5 and bridge["preflight.force"] is True
    default = dict(build_graph(GraphOptions(plant="hardware", clock_mode="realtime"))[-1].parameters)
    assert "preflight.duration_s" not in default and "preflight.force" not in default
    again = options_from_arguments(build_parser().parse_args(arguments_from_options(options)))
    assert again == options


@pytest.mark.parametrize("bad", [-1.0, 30.5, True, "3", float("nan")])
def test_a_preflight_duration_out_of_range_is_refused_with_its_name(bad: Any) -> None:
    with pytest.raises(ValueError, match="preflight"):
        GraphOptions(plant="hardware", clock_mode="realtime", preflight=bad)


def test_force_must_be_a_bool() -> None:
    with pytest.raises(ValueError, match="force"):
        GraphOptions(plant="hardware", clock_mode="realtime", force=1)  # type: ignore[arg-type]
