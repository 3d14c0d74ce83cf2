"""Every bad bag gets its typed error from the library and its exit code from the CLI."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from bag.bag_helpers import T0, joint_state, reference, torque
from smm_bag.cli import main
from smm_bag.commands import (
    EXIT_CORRUPT,
    EXIT_MISSING_TOPICS,
    EXIT_NOT_A_BAG,
    EXIT_PARAMS,
    EXIT_TRUNCATED,
)
from smm_analysis.runs.recorded import load_run
from smm_bag.writer import BagWriter, WriterOptions

from smm_bag import (
    BagReader,
    CorruptBagError,
    MissingTopicsError,
    NotABagError,
    TruncatedBagError,
)

MAKERS = {"/smm/joint_states": joint_state, "/smm/reference": reference, "/smm/torque_command": torque}


def good_bag(path: Path, topics: tuple[str, ...] = tuple(MAKERS)) -> Path:
    with BagWriter(path, WriterOptions(chunk_size=4096)) as writer:
        for topic in topics:
            kind = "sensor_msgs/msg/JointState" if "joint" in topic else "std_msgs/msg/Float64MultiArray"
            writer.create_topic(topic, kind)
        for k in range(200):
            for topic in topics:
                writer.write(topic, MAKERS[topic](k), T0 + k * 1_000_000)
    return path


def truncate(bag: Path) -> None:
    path = bag / f"{bag.name}_0.mcap"
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 2 // 3])


def bad_magic(bag: Path) -> None:
    path = bag / f"{bag.name}_0.mcap"
    path.write_bytes(b"NOTMCAP!" + path.read_bytes()[8:])


def flip_chunk_byte(bag: Path) -> None:
    path = bag / f"{bag.name}_0.mcap"
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0xFF  # inside a chunk's messages: the chunk CRC no longer matches
    path.write_bytes(bytes(data))


def wrong_count(bag: Path) -> None:
    path = bag / "metadata.yaml"
    document = yaml.safe_load(path.read_text())
    document["rosbag2_bagfile_information"]["topics_with_message_count"][0]["message_count"] += 1
    path.write_text(yaml.safe_dump(document))


def garbage_metadata(bag: Path) -> None:
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [1, 2\n")


def metadata_without_version(bag: Path) -> None:
    path = bag / "metadata.yaml"
    document = yaml.safe_load(path.read_text())
    del document["rosbag2_bagfile_information"]["version"]
    path.write_text(yaml.safe_dump(document))


def missing_file(bag: Path) -> None:
    (bag / f"{bag.name}_0.mcap").unlink()


def no_metadata(bag: Path) -> None:
    (bag / "metadata.yaml").unlink()


CASES: list[tuple[str, Callable[[Path], None], type[Exception], int]] = [
    ("no metadata.yaml", no_metadata, NotABagError, EXIT_NOT_A_BAG),
    ("truncated file", truncate, TruncatedBagError, EXIT_TRUNCATED),
    ("bad magic", bad_magic, CorruptBagError, EXIT_CORRUPT),
    ("counts disagree", wrong_count, CorruptBagError, EXIT_CORRUPT),
    ("metadata not YAML", garbage_metadata, CorruptBagError, EXIT_CORRUPT),
    ("metadata without version", metadata_without_version, CorruptBagError, EXIT_CORRUPT),
    ("storage file missing", missing_file, CorruptBagError, EXIT_CORRUPT),
]


@pytest.mark.parametrize(("damage", "error", "code"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
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
    assert main(["analyze", "--quiet", str(bag)]) == code
    assert "smm-bag: error:" in capsys.readouterr().err


def test_corrupt_chunk_is_reported_when_read(tmp_path: Path) -> None:
    bag = good_bag(tmp_path / "bag")
    flip_chunk_byte(bag)
    with pytest.raises(CorruptBagError, match="damaged"), BagReader(bag) as reader:
        list(reader.messages())
    assert main(["analyze", "--quiet", str(bag)]) == EXIT_CORRUPT


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


def test_missing_topics_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = good_bag(tmp_path / "bag", ("/smm/joint_states",))
    with pytest.raises(MissingTopicsError, match="/smm/reference, /smm/torque_command"):
        load_run(bag)
    assert main(["analyze", "--quiet", str(bag)]) == EXIT_MISSING_TOPICS
    assert main(["rerun", str(bag)]) == EXIT_MISSING_TOPICS
    assert "/smm/reference" in capsys.readouterr().err


def test_truncated_bag_readable_after_repair(tmp_path: Path) -> None:
    bag = good_bag(tmp_path / "bag")
    truncate(bag)
    assert main(["repair", str(bag)]) == 0
    with BagReader(bag) as reader:
        assert 0 < reader.message_count < 600
        assert sum(1 for _ in reader.messages()) == reader.message_count


def test_bad_params_file_exit_code(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    shutil.copytree(good_bag(tmp_path / "source"), bag)
    params = tmp_path / "params.yaml"
    params.write_text("not: [a, params, file\n")
    assert main(["rerun", str(bag), "--params-file", str(params)]) == EXIT_PARAMS
    params.write_text(
        "/**/controller_node:\n  ros__parameters:\n    fpdeso:\n      fuzzy:\n        kp0: [1.0]\n"
    )
    assert main(["rerun", str(bag), "--params-file", str(params)]) == EXIT_PARAMS
    params.write_text("/**/controller_node:\n  ros__parameters:\n    algorithm: lqr\n")
    assert main(["rerun", str(bag), "--params-file", str(params)]) == EXIT_PARAMS
    assert main(["rerun", str(bag), "--params-file", str(tmp_path / "absent.yaml")]) == EXIT_PARAMS
