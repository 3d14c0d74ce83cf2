"""``smm-bag info``: the size counts the bag's own files; repair's ``.damaged`` backups are shown apart."""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest
from bag.bag_helpers import flip_chunk_byte, good_bag
from smm_bag.cli import main
from smm_bag.commands import repair

from smm_bag import read_metadata

_UNITS = {"B": 1, "KiB": 1024, "MiB": 1024**2, "GiB": 1024**3}


def _bytes(text: str) -> tuple[float, int]:
    """A printed size (``1.2 MiB``) as (bytes, the unit in bytes)."""
    value, unit = text.split()
    return float(value) * _UNITS[unit], _UNITS[unit]


def _near(printed: str, expected: int) -> bool:
    value, unit = _bytes(printed)
    return abs(value - expected) <= 0.05 * unit  # printed with one decimal


def _info(bag: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["info", str(bag)]) == 0
    return capsys.readouterr().out


def _own_size(bag: Path) -> int:
    names = ["metadata.yaml", *read_metadata(bag).relative_file_paths]
    return sum((bag / name).stat().st_size for name in names)


def test_a_fresh_bag_shows_its_size_and_no_backups(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = good_bag(tmp_path / "bag")
    text = _info(bag, capsys)
    size = re.search(r"^Bag size: +(.+)$", text, re.MULTILINE)
    assert size is not None and _near(size.group(1), _own_size(bag))
    assert "Repair backups" not in text


def test_repair_backups_are_not_in_the_bag_size_and_are_listed_apart(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = good_bag(tmp_path / "bag")
    for _ in range(2):  # twice: bag_0.mcap.damaged, .damaged.2 and the same for metadata.yaml
        flip_chunk_byte(bag)
        assert repair(bag, stdout=io.StringIO(), stderr=io.StringIO()) == 0
    (bag / "notes.txt").write_text("not part of the bag\n" * 4000)
    backups = [
        "bag_0.mcap.damaged",
        "bag_0.mcap.damaged.2",
        "metadata.yaml.damaged",
        "metadata.yaml.damaged.2",
    ]
    assert all((bag / name).is_file() for name in backups)
    everything = sum(path.stat().st_size for path in bag.iterdir())
    own = _own_size(bag)
    assert everything > 2 * own  # the old count (the whole folder) cannot pass for the bag's own size

    text = _info(bag, capsys)
    size = re.search(r"^Bag size: +(.+)$", text, re.MULTILINE)
    assert size is not None and _near(size.group(1), own)
    line = re.search(
        r"^Repair backups: 4 files, (.+) \(\*\.damaged; not in the bag size\)$", text, re.MULTILINE
    )
    assert line is not None, text
    assert _near(line.group(1), sum((bag / name).stat().st_size for name in backups))
    assert text.index("Service information:") < text.index("Repair backups")  # after ros2 bag info's layout


def test_one_backup_is_one_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = good_bag(tmp_path / "bag")
    flip_chunk_byte(bag)
    assert repair(bag, stdout=io.StringIO(), stderr=io.StringIO()) == 0
    (bag / "metadata.yaml.damaged").unlink()
    text = _info(bag, capsys)
    assert re.search(r"^Repair backups: 1 file, ", text, re.MULTILINE), text
