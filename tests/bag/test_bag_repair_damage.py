"""smm-bag repair on real bags damaged at random places: what it keeps, checked message by message.

The full run (500 copies and more) is bench/bench_repair.py; here a fixed-seed few tens (the ``ci``
profile is derandomized).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from bag.repair_damage import (
    KINDS,
    SAMPLE,
    OriginalFile,
    Place,
    damage_copy,
    read_original,
    repair_and_check,
    write_source_bag,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

_PLACES = st.lists(
    st.builds(
        Place,
        kind=st.sampled_from(KINDS),
        file=st.integers(0, 7),
        where=st.floats(0.0, 1.0, exclude_max=True),
        bit=st.integers(0, 7),
    ),
    min_size=1,
    max_size=3,
)


@pytest.fixture(scope="module")
def sources(tmp_path_factory: pytest.TempPathFactory) -> list[tuple[Path, list[OriginalFile]]]:
    written = write_source_bag(tmp_path_factory.mktemp("source") / "written")
    return [(written, read_original(written)), (SAMPLE, read_original(SAMPLE))]


def test_the_written_source_has_several_files_and_many_chunks(
    sources: list[tuple[Path, list[OriginalFile]]],
) -> None:
    written = sources[0][1]
    assert len(written) >= 3
    assert sum(len(original.chunks) for original in written) >= 100


@pytest.mark.slow
@settings(max_examples=30, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from([0, 0, 0, 1]), places=_PLACES)
def test_repair_keeps_every_checked_message_of_a_damaged_copy(
    sources: list[tuple[Path, list[OriginalFile]]],
    tmp_path_factory: pytest.TempPathFactory,
    which: int,
    places: list[Place],
) -> None:
    source, originals = sources[which]
    damaged = damage_copy(source, originals, tmp_path_factory.mktemp("copy") / "bag", places)
    outcome = repair_and_check(source, originals, damaged)
    assert outcome.kept >= outcome.undamaged


def test_a_chunk_opcode_flipped_to_data_end_loses_no_other_chunk(
    sources: list[tuple[Path, list[OriginalFile]]], tmp_path: Path
) -> None:
    """Hypothesis found it: bits 0 and 3 of a file's first Chunk opcode (0x06 -> 0x0F, Data End)."""
    source, originals = sources[0]
    places = [Place("chunk bit flip", 1, 0.0, 0), Place("chunk bit flip", 1, 0.0, 3)]
    damaged = damage_copy(source, originals, tmp_path / "bag", places)
    assert (damaged.bag / originals[1].name).read_bytes()[originals[1].chunks[0][0]] == 0x0F
    outcome = repair_and_check(source, originals, damaged)
    assert outcome.kept >= outcome.undamaged > 0


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_of_damage_on_the_sample(
    sources: list[tuple[Path, list[OriginalFile]]], tmp_path: Path, kind: str
) -> None:
    source, originals = sources[1]
    damaged = damage_copy(source, originals, tmp_path / "bag", [Place(kind, 0, 0.37, 3)])
    outcome = repair_and_check(source, originals, damaged)
    assert outcome.intact_files + outcome.repaired_files == 1
    if kind == "metadata.yaml":
        assert outcome.kept == outcome.original and outcome.intact_files == 1
    else:
        assert outcome.repaired_files == 1
