"""Valid bags of shapes our writer never makes (issue 29): every command reads them, repair leaves them.

Each bag is the same run re-written with the ``mcap`` library; counts are checked against ``mcap``'s
StreamReader reading every record, never against statistics.
"""

from __future__ import annotations

import io
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml
from bag.bag_helpers import good_bag
from bag.foreign import QOS_V8, Shape, bag_messages, rewrite
from mcap.writer import Writer
from smm_analysis.runs.recorded import load_run
from smm_bag.commands import info, repair
from smm_bag.errors import OtherStorageError
from smm_bag.exit_codes import EXIT_MISSING_TOPICS, EXIT_OTHER_STORAGE
from smm_bag.player import playable
from smm_bag.reader import BagReader
from smm_bag.repair import repair_bag

from smm_bag import TopicInfo

SHAPES = [
    Shape(),
    Shape(chunked=False),
    Shape(chunked=False, crcs=False, statistics=False, indexes=False, summary_channels=False),
    Shape(compression="lz4"),
    Shape(compression="", crcs=False),
    Shape(statistics=False),
    Shape(indexes=False),
    Shape(summary_channels=False),
    Shape(files=3),
    Shape(file_compression=True),
    Shape(chunked=False, file_compression=True, files=2),
]


@pytest.fixture(scope="module")
def original(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return good_bag(tmp_path_factory.mktemp("original") / "run")


def _files(bag: Path) -> dict[str, bytes]:
    folder = bag if bag.is_dir() else bag.parent
    return {path.name: path.read_bytes() for path in folder.iterdir()}


def _read(bag: Path, ordered: bool) -> list[tuple[str, int, bytes]]:
    with BagReader(bag) as reader:
        return [(m.topic, m.log_time_ns, m.data) for m in reader.messages(ordered=ordered)]


# A bare file is one file: split shapes come in folders only.
LAYOUTS = [(shape, bare) for shape in SHAPES for bare in (False, True) if not (bare and shape.files > 1)]


@pytest.mark.parametrize(
    ("shape", "bare"),
    LAYOUTS,
    ids=[f"{shape.name}-{'bare file' if bare else 'folder'}" for shape, bare in LAYOUTS],
)
def test_every_valid_shape_reads_analyses_and_is_left_alone_by_repair(
    original: Path, tmp_path: Path, shape: Shape, bare: bool
) -> None:
    bag = rewrite(original, tmp_path / "copy", shape, None if bare else 9)
    stored = bag_messages(bag)
    assert len(stored) == 600
    assert Counter(_read(bag, ordered=False)) == Counter(stored)
    in_time = _read(bag, ordered=True)
    assert Counter(in_time) == Counter(stored)
    assert [time for _, time, _ in in_time] == sorted(time for _, time, _ in stored)
    with BagReader(bag) as reader:
        assert {t.name: t.message_count for t in reader.metadata.topics} == dict(
            Counter(topic for topic, _, _ in stored)
        )
    out = io.StringIO()
    assert info(bag, stdout=out, stderr=io.StringIO()) == 0
    assert "Messages:          600" in out.getvalue()
    ours, theirs = load_run(original), load_run(bag)
    for name in ("t_ns", "reference", "position", "command_torque", "measured_position"):
        assert np.array_equal(getattr(ours, name), getattr(theirs, name)), name
    before = _files(bag)
    report = repair_bag(bag)
    assert {item.status for item in report.files} == {"intact"}, [item.findings for item in report.files]
    assert not report.metadata_rewritten
    assert _files(bag) == before


def test_message_compression_is_undone_as_rosbag2_reads_it(original: Path, tmp_path: Path) -> None:
    bag = rewrite(original, tmp_path / "copy", Shape(message_compression=True), 9)
    with BagReader(original) as reader:
        plain = Counter((m.topic, m.log_time_ns, m.data) for m in reader.messages())
    assert Counter(_read(bag, ordered=True)) == plain
    ours, theirs = load_run(original), load_run(bag)
    assert np.array_equal(ours.command_torque, theirs.command_torque)


@pytest.mark.parametrize("version", [4, 5, 6, 7, 8, 9])
def test_metadata_versions_4_to_9_read_and_rebuilt_in_their_own_version(
    original: Path, tmp_path: Path, version: int
) -> None:
    bag = rewrite(original, tmp_path / "copy", Shape(chunked=False, crcs=False), version)
    with BagReader(bag) as reader:
        profile = reader.metadata.topics[0].offered_qos_profiles[0]
    assert (profile.liveliness, profile.reliability, profile.durability) == (
        "manual_by_topic",
        "reliable",
        "volatile",
    )
    assert profile.deadline_ns == 9_223_372_036_854_775_807
    before = (bag / "metadata.yaml").read_bytes()
    assert not repair_bag(bag).metadata_rewritten  # layout and QoS spelling are not damage
    assert (bag / "metadata.yaml").read_bytes() == before
    document = yaml.safe_load(before)
    document["rosbag2_bagfile_information"]["topics_with_message_count"][0]["message_count"] += 5
    (bag / "metadata.yaml").write_text(yaml.safe_dump(document))
    report = repair_bag(bag)
    assert report.metadata_rewritten and (bag / "metadata.yaml.damaged").exists()
    rebuilt = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert rebuilt["version"] == version
    qos = rebuilt["topics_with_message_count"][0]["topic_metadata"]["offered_qos_profiles"]
    if version >= 9:
        assert qos[0]["liveliness"] == "manual_by_topic"
    else:  # rosbag2 reads a version <= 8 profile list as one YAML string of enum integers
        assert isinstance(qos, str)
        assert yaml.safe_load(qos)[0]["liveliness"] == QOS_V8["liveliness"]
    assert rebuilt["topics_with_message_count"][0]["message_count"] == 200
    with BagReader(bag) as reader:
        assert reader.message_count == 600


def test_other_storage_is_named_with_its_own_exit_code(tmp_path: Path) -> None:
    """ROS 1 and storage plugins not read here (sqlite3 is read: tests/bag/test_sqlite3.py)."""
    ros1 = tmp_path / "old.bag"
    ros1.write_bytes(b"#ROSBAG V2.0\n" + bytes(100))
    folder = tmp_path / "plugin_bag"
    folder.mkdir()
    (folder / "metadata.yaml").write_text(
        yaml.safe_dump({"rosbag2_bagfile_information": {"version": 9, "storage_identifier": "custom_plugin"}})
    )
    for bag in (ros1, folder):
        for command in (info, repair):
            err = io.StringIO()
            assert command(bag, stdout=io.StringIO(), stderr=err) == EXIT_OTHER_STORAGE
            line = [text for text in err.getvalue().splitlines() if "error" in text]
            assert len(line) == 1 and ("custom_plugin" in line[0] or "ROS 1" in line[0]), err.getvalue()
    with pytest.raises(OtherStorageError, match="custom_plugin"):
        BagReader(folder)


def _plain_file(path: Path, topics: dict[str, str], count: int) -> Path:
    """A bare MCAP file with ``count`` messages on each topic (name -> type), written by ``mcap``."""
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start("ros2", "tests")
        for number, (topic, kind) in enumerate(topics.items()):
            schema = writer.register_schema(kind, "ros2msg", b"")
            channel = writer.register_channel(topic, "cdr", schema)
            for k in range(count):
                writer.add_message(channel, 1_000 * k + number, b"\x00\x01\x00\x00", 1_000 * k)
        writer.finish()  # type: ignore[no-untyped-call]
    return path


def test_info_lists_service_event_topics_as_services(tmp_path: Path) -> None:
    topics = {"/a": "std_msgs/msg/Empty", "/set_mode/_service_event": "std_srvs/srv/Trigger_Event"}
    bag = _plain_file(tmp_path / "services.mcap", topics, 7)
    out = io.StringIO()
    assert info(bag, stdout=out, stderr=io.StringIO()) == 0
    text = out.getvalue()
    assert "Messages:          7\n" in text  # as ros2 bag info: service events are not counted as messages
    assert "Topic information: Topic: /a | Type: std_msgs/msg/Empty | Count: 7" in text
    assert "Service:           1\n" in text
    assert "Service information: Service: /set_mode | Type: std_srvs/srv/Trigger | Event Count: 7" in text
    assert "_service_event" not in text


def test_topics_that_cannot_be_played_are_named_and_the_rest_play() -> None:
    assert playable(TopicInfo("/a", "std_msgs/msg/Float64MultiArray"))[0] is not None
    for topic, why in (
        (TopicInfo("/b", "no_such_pkg/msg/Thing"), "not installed"),
        (TopicInfo("/c", "std_msgs/msg/String", serialization_format="json"), "not CDR"),
        (TopicInfo("/d/_service_event", "std_srvs/srv/Trigger_Event"), "service events"),
    ):
        kind, reason = playable(topic)
        assert kind is None and why in reason


def test_analyze_of_a_bag_without_the_stack_topics_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from smm_bag.cli import main

    bag = _plain_file(tmp_path / "camera.mcap", {"/camera/image": "sensor_msgs/msg/Image"}, 5)
    assert main(["analyze", str(bag)]) == EXIT_MISSING_TOPICS
    err = capsys.readouterr().err
    assert len([line for line in err.splitlines() if "error" in line]) == 1, err
    assert "/smm/joint_states" in err and "Traceback" not in err
