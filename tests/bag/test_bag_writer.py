"""The writer makes rosbag2 bags that rosbags' AnyReader and mcap + mcap-ros2-support both read alike."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from bag.bag_helpers import T0, TOPICS, TYPESTORE, as_array, joint_state, mcap_messages, rosbags_messages
from mcap.reader import make_reader
from smm_bag.msgdefs import message_definition
from smm_bag.repair import repair_bag
from smm_bag.writer import BagWriter, WriterOptions

from smm_bag import BagExistsError, BagReader, QosProfile, WriterStateError, read_metadata

CONTROL = QosProfile(depth=10)


def write_all_types(path: Path, count: int, options: WriterOptions | None = None) -> dict[str, int]:
    written = {}
    with BagWriter(path, options) as writer:
        for topic, (type_name, _) in TOPICS.items():
            writer.create_topic(topic, type_name, [CONTROL])
        for k in range(count):
            for index, (topic, (_, make)) in enumerate(TOPICS.items()):
                if topic in ("/diagnostics", "/rosout", "/parameter_events") and k % 10:
                    continue
                writer.write(topic, make(k), T0 + k * 1_000_000 + index, T0 + k * 1_000_000)
                written[topic] = written.get(topic, 0) + 1
    return written


@pytest.mark.parametrize(
    "options",
    [
        WriterOptions(),
        WriterOptions(compression="zstd"),
        WriterOptions(max_duration_ns=100_000_000),
        WriterOptions(max_size_bytes=64 * 1024, chunk_size=16 * 1024),
    ],
    ids=["plain", "zstd", "split-duration", "split-size"],
)
def test_both_readers_agree_with_each_other_and_with_metadata(tmp_path: Path, options: WriterOptions) -> None:
    bag = tmp_path / "bag"
    written = write_all_types(bag, 300, options)
    metadata = read_metadata(bag)
    counts = {topic.name: topic.message_count for topic in metadata.topics}
    assert counts == written
    assert metadata.message_count == sum(written.values())
    by_rosbags, by_mcap = rosbags_messages(bag), mcap_messages(bag)
    assert {t: len(m) for t, m in by_rosbags.items()} == counts
    assert {t: len(m) for t, m in by_mcap.items()} == counts
    assert sum(info.message_count for info in metadata.files) == metadata.message_count
    if options.max_duration_ns or options.max_size_bytes:
        assert len(metadata.files) > 1
    assert [path.name for path in sorted(bag.glob("*.mcap"))] == sorted(metadata.relative_file_paths)
    for topic in counts:
        for (time_a, a), (time_b, b) in zip(by_rosbags[topic], by_mcap[topic], strict=True):
            assert time_a == time_b
            if topic == "/smm/joint_states":
                assert a.header.stamp.nanosec == b.header.stamp.nanosec
                np.testing.assert_array_equal(a.position, as_array(b.position))
                np.testing.assert_array_equal(a.effort, as_array(b.effort))
                assert list(a.name) == list(b.name) == ["alpha", "beta"]
            elif topic == "/smm/torque_command":
                np.testing.assert_array_equal(a.data, as_array(b.data))
                assert [d.label for d in a.layout.dim] == [d.label for d in b.layout.dim]
            elif topic == "/clock":
                assert a.clock.sec == b.clock.sec
            elif topic == "/rosout":
                assert a.msg == b.msg and a.line == b.line
            elif topic == "/diagnostics":
                assert a.status[0].values[0].value == b.status[0].values[0].value
            else:
                assert a.node == b.node
    # Values are the written ones.
    first = by_rosbags["/smm/joint_states"][7][1]
    np.testing.assert_array_equal(first.position, [0.007, -0.014])
    assert by_rosbags["/smm/joint_states"][7][0] == T0 + 7_000_000


def test_metadata_yaml_is_rosbag2_version_9(tmp_path: Path) -> None:
    bag = tmp_path / "run"
    custom = {"smm.scenario": "case2"}
    write_all_types(bag, 20, WriterOptions(custom_data=custom))
    document = yaml.safe_load((bag / "metadata.yaml").read_text())
    info = document["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["ros_distro"] == "jazzy"
    assert info["relative_file_paths"] == ["run_0.mcap"]
    assert info["files"][0]["path"] == "run_0.mcap"
    assert info["files"][0]["message_count"] == info["message_count"]
    assert info["starting_time"]["nanoseconds_since_epoch"] == T0
    assert info["duration"]["nanoseconds"] == 19 * 1_000_000 + 2  # /clock, index 2, of step 19 is last
    assert info["custom_data"]["smm.scenario"] == "case2"
    assert info["compression_format"] == "" and info["compression_mode"] == ""
    topic = info["topics_with_message_count"][0]
    assert topic["topic_metadata"]["type_description_hash"].startswith("RIHS01_")
    qos = topic["topic_metadata"]["offered_qos_profiles"][0]
    assert qos["history"] == "keep_last" and qos["depth"] == 10 and qos["reliability"] == "reliable"
    assert qos["durability"] == "volatile" and qos["liveliness"] == "automatic"
    assert qos["deadline"] == {"sec": 9223372036, "nsec": 854775807}
    assert qos["avoid_ros_namespace_conventions"] is False


def test_mcap_follows_rosbag2_storage_mcap_conventions(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    write_all_types(bag, 5)
    with (bag / "bag_0.mcap").open("rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            assert channel.message_encoding == "cdr"
            assert schema.encoding == "ros2msg"
            assert schema.name == TOPICS[channel.topic][0]
            assert schema.data.decode() == message_definition(schema.name).text
            assert channel.metadata["topic_type_hash"] == TYPESTORE.hash_rihs01(schema.name)
            profiles = yaml.safe_load(channel.metadata["offered_qos_profiles"])
            assert profiles[0]["reliability"] == "reliable"
        records = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
        assert len(records) == 2  # at open and at close, as rosbag2 writes them
        final = yaml.safe_load(records[-1].metadata["serialized_metadata"])
        on_disk = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        assert final["message_count"] == on_disk["message_count"]
        assert final["topics_with_message_count"] == on_disk["topics_with_message_count"]


def test_message_definitions_are_the_full_concatenated_msg_text() -> None:
    definition = message_definition("sensor_msgs/msg/JointState")
    parts = definition.text.split("=" * 80 + "\n")
    assert "std_msgs/Header header" in parts[0] and "float64[] effort" in parts[0]
    assert parts[1].startswith("MSG: std_msgs/Header\n")
    assert parts[2].startswith("MSG: builtin_interfaces/Time\n")
    assert message_definition("sensor_msgs/JointState") == definition
    diagnostics = message_definition("diagnostic_msgs/msg/DiagnosticArray").text
    assert (
        "MSG: diagnostic_msgs/DiagnosticStatus" in diagnostics
        and "MSG: diagnostic_msgs/KeyValue" in diagnostics
    )
    for type_name in {type_name for type_name, _ in TOPICS.values()}:
        assert message_definition(type_name).type_hash == TYPESTORE.hash_rihs01(type_name)


def test_metadata_yaml_exists_at_open_and_after_each_split(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    writer = BagWriter(bag, WriterOptions(max_duration_ns=10_000_000))
    assert read_metadata(bag).relative_file_paths == ("bag_0.mcap",)
    writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState", [CONTROL])
    assert read_metadata(bag).topics[0].name == "/smm/joint_states"
    for k in range(25):
        writer.write("/smm/joint_states", joint_state(k), T0 + k * 1_000_000)
    during = read_metadata(bag)
    assert during.relative_file_paths == ("bag_0.mcap", "bag_1.mcap", "bag_2.mcap")
    assert during.files[0].message_count == 10 and during.files[1].message_count == 10
    writer.split()
    assert len(read_metadata(bag).files) == 4
    final = writer.close()
    assert final.message_count == 25
    assert BagReader(bag).message_count == 25


def test_flush_interval_bounds_what_a_crash_loses(tmp_path: Path) -> None:
    bag, crashed = tmp_path / "bag", tmp_path / "crashed"
    now = [0]
    writer = BagWriter(bag, WriterOptions(flush_interval_ns=100_000_000), clock=lambda: now[0])
    writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState", [CONTROL])
    for k in range(1000):
        now[0] = k * 1_000_000  # 1 kHz, flushes every 100 messages
        writer.write("/smm/joint_states", joint_state(k), T0 + k * 1_000_000)
    shutil.copytree(bag, crashed)  # what is on disk if the process dies now
    writer.close()
    report = repair_bag(crashed)
    recovered = report.metadata.topic("/smm/joint_states")
    assert recovered is not None
    assert 1000 - 100 <= recovered.message_count < 1000
    times = [t for t, _ in rosbags_messages(crashed)["/smm/joint_states"]]
    assert times == [T0 + k * 1_000_000 for k in range(recovered.message_count)]


def test_writer_refuses_misuse(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    with pytest.raises(BagExistsError, match="never overwrites"):
        BagWriter(bag)
    writer = BagWriter(tmp_path / "other")
    with pytest.raises(WriterStateError, match="before create_topic"):
        writer.write("/x", b"", T0)
    writer.create_topic("/x", "std_msgs/msg/Float64MultiArray")
    with pytest.raises(WriterStateError, match="already created"):
        writer.create_topic("/x", "std_msgs/msg/Float64MultiArray")
    writer.close()
    with pytest.raises(WriterStateError, match="closed"):
        writer.write("/x", b"", T0)
    for bad in (
        {"flush_interval_ns": 0},
        {"flush_interval_ns": 2_000_000_000},
        {"max_size_bytes": 10},
        {"compression": "lz4"},
        {"max_duration_ns": -1},
    ):
        with pytest.raises(ValueError):
            WriterOptions(**bad)  # type: ignore[arg-type]


def test_loss_accounting_counts_received_written_and_stamp_gaps(tmp_path: Path) -> None:
    writer = BagWriter(tmp_path / "bag", WriterOptions(stamped_topics=frozenset({"/smm/joint_states"})))
    writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState")
    for k in [*range(10), *range(13, 20)]:  # samples 10, 11, 12 never arrive
        writer.write("/smm/joint_states", joint_state(k), T0 + k * 1_000_000)
    writer.loss.received("/smm/joint_states", 2)  # handed over but dropped before storage
    metadata = writer.close()
    counters = writer.loss.as_dict()["/smm/joint_states"]
    assert counters == {
        "received": 19,
        "written": 17,
        "lost": 2,
        "stamp_gaps": 1,
        "stamp_missing": 3,
        "stamp_out_of_order": 0,
    }
    assert '"stamp_missing": 3' in metadata.custom_data["smm.loss"]


def test_the_run_after_a_rehearsal_stamped_an_hour_ahead_has_its_stamp_gaps_counted(tmp_path: Path) -> None:
    """The preflight's rehearsal comes first, an hour ahead; the run's stamps start a new timeline."""
    writer = BagWriter(tmp_path / "bag", WriterOptions(stamped_topics=frozenset({"/smm/joint_states"})))
    writer.create_topic("/smm/joint_states", "sensor_msgs/msg/JointState")
    hour = 3_600_000  # steps of 1 ms
    stamps = [*(hour + k for k in range(10)), *range(20, 30), *range(33, 40)]  # 30, 31, 32 never arrive
    for received, k in enumerate(stamps):
        writer.write("/smm/joint_states", joint_state(k), T0 + received * 1_000_000)
    writer.close()
    counters = writer.loss.as_dict()["/smm/joint_states"]
    assert counters["stamp_gaps"] == 1 and counters["stamp_missing"] == 3
    assert counters["stamp_out_of_order"] == 0
