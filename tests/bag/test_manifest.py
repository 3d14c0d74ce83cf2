"""RunManifest <-> a bag's custom_data."""

from __future__ import annotations

import pytest
from smm_bag.errors import CorruptBagError
from smm_bag.manifest import RunManifest


def test_the_nodes_left_unread_survive_the_round_trip_and_only_when_there_are_some() -> None:
    manifest = RunManifest(scenario="case2", parameters={"/smm/a": {"k": 1.5}}, parameters_unread=("/smm/b",))
    data = manifest.to_custom_data()
    assert RunManifest.from_custom_data(data) == manifest
    assert "smm.parameters_unread" not in RunManifest(scenario="case2").to_custom_data()
    assert RunManifest.from_custom_data(RunManifest().to_custom_data()).parameters_unread == ()


@pytest.mark.parametrize("text", ["{a: 1}", "[1, 2]", "[a, [b]]", "[unclosed"])
def test_a_malformed_list_of_unread_nodes_is_a_corrupt_manifest(text: str) -> None:
    data = RunManifest().to_custom_data() | {"smm.parameters_unread": text}
    with pytest.raises(CorruptBagError, match="run manifest"):
        RunManifest.from_custom_data(data)


@pytest.mark.parametrize(("seed", "text"), [(0, "0"), (7, "7"), (None, "")])
def test_seed_0_is_recorded_as_0_and_only_an_unknown_seed_as_empty(seed: int | None, text: str) -> None:
    data = RunManifest(seed=seed).to_custom_data()
    assert data["smm.seed"] == text
    assert RunManifest.from_custom_data(data).seed == seed
