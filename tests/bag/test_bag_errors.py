"""Every bad bag gets its typed error from the library and its exit code from the CLI."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from bag.bag_helpers import DAMAGES, flip_chunk_byte, good_bag, truncate
from smm_bag.cli import main
from smm_bag.exit_codes import EXIT_NOT_A_BAG

from smm_bag import BagReader, CorruptBagError, NotABagError


@pytest.mark.parametrize(("damage", "error", "code"), [c[1:] for c in DAMAGES], ids=[c[0] for c in DAMAGES])
def test_damaged_bag_gets_its_error_and_exit_code(
    tmp_path: Path,
    damage: Callable[[Path], None],
    error: type[Exception],
    code: int,
    capsys: pytest.CaptureFixture[str],
) -> None:
    bag = good_bag(tmp_path / "bag")
    damage(bag)
    with pytest.raises(error):
        BagReader(bag)
    assert main(["info", str(bag)]) == code
    assert "smm-bag: error:" in capsys.readouterr().err


def test_corrupt_chunk_is_reported_when_read(tmp_path: Path) -> None:
    bag = good_bag(tmp_path / "bag")
    flip_chunk_byte(bag)
    with pytest.raises(CorruptBagError, match="damaged"), BagReader(bag) as reader:
        list(reader.messages())


def test_folder_that_is_not_a_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(NotABagError, match=r"no metadata\.yaml"):
        BagReader(tmp_path)
    with pytest.raises(NotABagError, match="not a directory"):
        BagReader(tmp_path / "nothing")
    (tmp_path / "file.mcap").write_bytes(b"x")
    with pytest.raises(NotABagError, match="not a directory"):
        BagReader(tmp_path / "file.mcap")
    assert main(["info", str(tmp_path)]) == EXIT_NOT_A_BAG
    assert main(["repair", str(tmp_path / "nothing")]) == EXIT_NOT_A_BAG
    assert "not a" in capsys.readouterr().err


def test_truncated_bag_readable_after_repair(tmp_path: Path) -> None:
    bag = good_bag(tmp_path / "bag")
    truncate(bag)
    assert main(["repair", str(bag)]) == 0
    with BagReader(bag) as reader:
        assert 0 < reader.message_count < 600
        assert sum(1 for _ in reader.messages()) == reader.message_count
