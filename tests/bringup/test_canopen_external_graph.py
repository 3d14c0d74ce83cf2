"""``--link canopen --board external`` in lockstep: the bridge alone, its SYNC the bench's clock."""

from __future__ import annotations

import pytest
from smm_bringup.errors import PlantNotAvailableError
from smm_bringup.graph import build_graph
from smm_bringup.graph_nodes import EMULATOR_NODE, HW_NODE
from smm_bringup.graph_options import GraphOptions


def test_an_external_canopen_bench_runs_in_lockstep_without_an_emulator() -> None:
    specs = build_graph(GraphOptions(plant="hardware", link="canopen", board="external"))
    names = [spec.name for spec in specs]
    assert HW_NODE in names and EMULATOR_NODE not in names
    bridge = dict(next(spec for spec in specs if spec.name == HW_NODE).parameters)
    assert bridge["link.transport"] == "canopen" and bridge["bridge.lockstep"] is True
    assert not any(name.endswith("valve_eds") for name in bridge)  # a real bench: the user's EDS files


def test_a_frame_board_in_lockstep_stays_refused() -> None:
    with pytest.raises(PlantNotAvailableError, match="lockstep needs the emulator"):
        build_graph(GraphOptions(plant="hardware", board="10.0.0.7:6000"))
