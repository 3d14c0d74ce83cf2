"""sqlite3 bags (rosbag2's default before Iron), written by rosbags: info, analyze and convert to MCAP.

The sqlite3 copy of the committed sample runs through the corpus too (``rosbags-sqlite3``: info, analyze's
metrics, rerun); rosbag2's own sqlite3 test bags through ``make test-bags UPSTREAM=DIR`` (docs/BAGS.md).
"""

from __future__ import annotations

import io
import json
import sqlite3
from collections import Counter
from pathlib import Path

import pytest
import yaml
import zstandard
from bag.bag_helpers import good_bag
from bag.corpus.run import info_counts, metrics_values
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader as RosbagsReader
from rosbags.rosbag2 import Writer as RosbagsWriter
from rosbags.rosbag2.enums import StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from smm_bag.cli import main
from smm_bag.commands import info
from smm_bag.convert import convert_bag
from smm_bag.errors import CorruptBagError, NotABagError
from smm_bag.exit_codes import EXIT_CORRUPT, EXIT_NOT_A_BAG, EXIT_OK, EXIT_OTHER_STORAGE, EXIT_USAGE
from smm_bag.msgdefs import message_definition
from smm_bag.reader import BagReader

CUSTOM = "smm_sqlite_test_msgs/msg/Reading"
CUSTOM_TEXT = "float64 value\nstring unit\n"
"""A type no installed package defines: only the bag's own stored definition knows it."""
COUNTS = {"/words": 7, "/readings": 5, "/silent": 0}


def sqlite_bag(path: Path, version: int = 9) -> Path:
    """rosbags' writer, storage sqlite3: strings, a custom type, a topic without messages, custom data."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(CUSTOM_TEXT, CUSTOM))
    writer = RosbagsWriter(path, version=version, storage_plugin=StoragePlugin.SQLITE3)
    writer.set_custom_data("smm.scenario", "case2")
    writer.open()
    words = writer.add_connection("/words", "std_msgs/msg/String", typestore=store)
    readings = writer.add_connection("/readings", CUSTOM, typestore=store)
    writer.add_connection("/silent", "std_msgs/msg/String", typestore=store)
    string, reading = store.types["std_msgs/msg/String"], store.types[CUSTOM]
    for k in range(COUNTS["/words"]):
        stamp = 1_700_000_000_000_000_000 + k * 10_000_000
        writer.write(words, stamp, store.serialize_cdr(string(data=f"word {k}"), "std_msgs/msg/String"))
        if k < COUNTS["/readings"]:
            data = store.serialize_cdr(reading(value=0.5 * k, unit="bar"), CUSTOM)
            writer.write(readings, stamp + 1, data)
    writer.close()
    return path


def rosbags_read(bag: Path) -> Counter[tuple[str, int, bytes]]:
    with RosbagsReader(bag) as reader:
        return Counter((c.topic, t, bytes(d)) for c, t, d in reader.messages())


def mcap_read(bag: Path) -> Counter[tuple[str, int, bytes]]:
    found: Counter[tuple[str, int, bytes]] = Counter()
    for path in sorted(bag.glob("*.mcap")):
        with path.open("rb") as stream:
            for _, channel, message in make_reader(stream).iter_messages():
                found[(channel.topic, message.log_time, message.data)] += 1
    return found


@pytest.mark.parametrize("version", [8, 9])
def test_info_counts_a_sqlite3_bag_as_its_files_hold_folder_and_bare_file(
    tmp_path: Path, version: int
) -> None:
    bag = sqlite_bag(tmp_path / "bag", version)
    (db3,) = bag.glob("*.db3")
    expected = Counter(topic for topic, _, _ in rosbags_read(bag))
    for given in (bag, db3):
        out, err = io.StringIO(), io.StringIO()
        assert info(given, stdout=out, stderr=err) == EXIT_OK, err.getvalue()
        total, topics = info_counts(out.getvalue())
        assert total == sum(COUNTS.values()) and +topics == expected, out.getvalue()
        assert "Storage id:        sqlite3" in out.getvalue()
        assert "Topic: /silent | Type: std_msgs/msg/String | Count: 0" in out.getvalue()
        assert "smm.scenario: case2" in out.getvalue()


def test_messages_are_read_in_time_order_with_their_bytes(tmp_path: Path) -> None:
    bag = sqlite_bag(tmp_path / "bag")
    with BagReader(bag) as reader:
        read = [(m.topic, m.log_time_ns, m.data) for m in reader.messages()]
        assert reader.topics["/readings"] == CUSTOM
    assert Counter(read) == rosbags_read(bag)
    assert [t for _, t, _ in read] == sorted(t for _, t, _ in read)


def test_counts_that_disagree_with_metadata_yaml_are_corrupt(tmp_path: Path) -> None:
    bag = sqlite_bag(tmp_path / "bag")
    (db3,) = bag.glob("*.db3")
    with sqlite3.connect(db3) as db:
        db.execute("DELETE FROM messages WHERE id = (SELECT MIN(id) FROM messages)")
    db.close()
    with pytest.raises(
        CorruptBagError, match=r"metadata.yaml says 7 messages on /words, the storage files hold 6"
    ):
        BagReader(bag)


def test_an_sqlite3_file_without_rosbag2_tables_is_corrupt_in_one_line(tmp_path: Path) -> None:
    path = tmp_path / "other.db3"
    sqlite3.connect(path).execute("create table messages (id integer)").close()
    err = io.StringIO()
    assert info(path, stdout=io.StringIO(), stderr=err) == EXIT_CORRUPT
    assert [line for line in err.getvalue().splitlines() if "error" in line] == [
        f"smm-bag: error: {path}: an sqlite3 file without rosbag2's topics and messages tables"
    ]


def test_convert_gives_an_mcap_bag_that_info_and_both_readers_agree_on(tmp_path: Path) -> None:
    bag = sqlite_bag(tmp_path / "bag")
    out = tmp_path / "converted"
    result = convert_bag(bag, out)
    assert (result.source_storage, result.messages, result.topics) == ("sqlite3", 12, 3)
    assert result.undefined_types == ()
    assert mcap_read(out) == rosbags_read(out) == rosbags_read(bag)
    text = io.StringIO()
    assert info(out, stdout=text) == EXIT_OK
    total, topics = info_counts(text.getvalue())
    assert total == 12 and topics == Counter(COUNTS), text.getvalue()
    document = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert document["storage_identifier"] == "mcap"
    assert document["custom_data"] == {"smm.scenario": "case2"}  # no loss report of its own
    with (next(out.glob("*.mcap"))).open("rb") as stream:
        schemas = {s.name: s for s in make_reader(stream).get_summary().schemas.values()}
    (db3,) = bag.glob("*.db3")
    with sqlite3.connect(db3) as db:
        (stored,) = db.execute(
            "SELECT encoded_message_definition FROM message_definitions WHERE topic_type = ?", (CUSTOM,)
        ).fetchone()
    db.close()
    assert "float64 value" in stored and schemas[CUSTOM].data.decode() == stored  # the bag's own definition
    assert schemas[CUSTOM].encoding == "ros2msg"
    with BagReader(bag) as source, BagReader(out) as converted:
        assert converted.metadata.topics == source.metadata.topics  # names, types, QoS, hashes, counts


def test_convert_of_a_type_defined_nowhere_stores_it_without_definition_as_rosbag2_does(
    tmp_path: Path,
) -> None:
    bag = sqlite_bag(tmp_path / "bag", version=8)
    (db3,) = bag.glob("*.db3")
    with sqlite3.connect(db3) as db:  # a Humble bag: no stored definitions
        db.execute("DELETE FROM message_definitions")
    db.close()
    assert main(["convert", str(bag), str(tmp_path / "converted")]) == EXIT_OK
    result = convert_bag(bag, tmp_path / "again")
    assert result.undefined_types == (CUSTOM,)
    with (next((tmp_path / "again").glob("*.mcap"))).open("rb") as stream:
        schemas = {s.name: s for s in make_reader(stream).get_summary().schemas.values()}
    assert (schemas[CUSTOM].encoding, schemas[CUSTOM].data) == ("", b"")
    installed = message_definition("std_msgs/msg/String").text.encode()
    assert schemas["std_msgs/msg/String"].data == installed
    assert mcap_read(tmp_path / "again") == rosbags_read(tmp_path / "again") == rosbags_read(bag)


def test_convert_refuses_an_existing_output_and_changes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = sqlite_bag(tmp_path / "bag")
    target = tmp_path / "taken"
    target.mkdir()
    (target / "keep.txt").write_text("mine")
    assert main(["convert", str(bag), str(target)]) == EXIT_USAGE
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("smm-bag: error:")]
    assert len(errors) == 1 and "exists" in errors[0]
    assert [p.name for p in target.iterdir()] == ["keep.txt"]


def test_repair_refuses_sqlite3_naming_convert(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = sqlite_bag(tmp_path / "bag")
    before = {p.name: p.read_bytes() for p in bag.iterdir()}
    assert main(["repair", str(bag)]) == EXIT_OTHER_STORAGE
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("smm-bag: error:")]
    assert len(errors) == 1 and "smm-bag convert" in errors[0]
    assert {p.name: p.read_bytes() for p in bag.iterdir()} == before


def test_analyze_of_the_sqlite3_copy_equals_the_mcap_original(tmp_path: Path) -> None:
    original = good_bag(tmp_path / "original")
    copy = tmp_path / "copy"
    writer = RosbagsWriter(copy, version=9, storage_plugin=StoragePlugin.SQLITE3)
    writer.open()
    store = get_typestore(Stores.ROS2_JAZZY)
    with BagReader(original) as reader:
        connections = {
            topic.name: writer.add_connection(topic.name, topic.type, typestore=store)
            for topic in reader.metadata.topics
        }
        for message in reader.messages():
            writer.write(connections[message.topic], message.log_time_ns, message.data)
    writer.close()
    reports = []
    for bag in (original, copy):
        out = tmp_path / f"metrics_{bag.name}"
        assert main(["analyze", str(bag), "--out", str(out), "--no-plots", "--quiet"]) == EXIT_OK
        reports.append(metrics_values(json.loads((out / "metrics.json").read_text())))
    assert reports[0] == reports[1] and '"steps": 200' in reports[0]  # equal bits, names aside


def test_a_folder_with_mcap_files_and_no_metadata_names_repair_which_rebuilds_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = good_bag(tmp_path / "bag")
    with BagReader(bag) as reader:
        counts = {t.name: t.message_count for t in reader.metadata.topics}
    (bag / "metadata.yaml").unlink()
    with pytest.raises(NotABagError, match=rf"`smm-bag repair {bag}` rebuilds it"):
        BagReader(bag)
    assert main(["info", str(bag)]) == EXIT_NOT_A_BAG
    assert "smm-bag repair" in capsys.readouterr().err
    assert main(["repair", str(bag)]) == EXIT_OK
    with BagReader(bag) as reader:
        assert {t.name: t.message_count for t in reader.metadata.topics} == counts


def test_a_folder_of_db3_files_without_metadata_names_the_file_to_give(tmp_path: Path) -> None:
    bag = sqlite_bag(tmp_path / "bag")
    (bag / "metadata.yaml").unlink()
    (db3,) = bag.glob("*.db3")
    with pytest.raises(NotABagError, match=rf"smm-bag info {db3}"):
        BagReader(bag)
    with BagReader(db3) as reader:
        assert reader.message_count == 12


def test_a_file_compressed_sqlite3_bag_reads_as_the_plain_one(tmp_path: Path) -> None:
    bag = sqlite_bag(tmp_path / "bag")
    plain = rosbags_read(bag)
    (db3,) = bag.glob("*.db3")
    packed = db3.with_name(db3.name + ".zstd")
    packed.write_bytes(zstandard.ZstdCompressor().compress(db3.read_bytes()))
    db3.unlink()
    document = yaml.safe_load((bag / "metadata.yaml").read_text())
    node = document["rosbag2_bagfile_information"]
    node.update(relative_file_paths=[packed.name], compression_format="zstd", compression_mode="FILE")
    for entry in node["files"]:
        entry["path"] = packed.name
    (bag / "metadata.yaml").write_text(yaml.safe_dump(document))
    for given in (bag, packed):
        with BagReader(given) as reader:
            assert Counter((m.topic, m.log_time_ns, m.data) for m in reader.messages()) == plain
