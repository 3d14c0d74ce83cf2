"""Helpers of the bag tests: messages of every recorded type, serialized as on the wire, and both readers."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from smm_bag.cdr import encode_float64_multi_array, encode_joint_state
from smm_bag.exit_codes import EXIT_CORRUPT, EXIT_NOT_A_BAG, EXIT_TRUNCATED
from smm_bag.reader import BagMessage, BagReader
from smm_bag.writer import BagWriter, WriterOptions

from smm_bag import CorruptBagError, NotABagError, TruncatedBagError

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
T0 = 1_700_000_000_000_000_000


def joint_state(k: int) -> bytes:
    return encode_joint_state(k * 1_000_000, ["alpha", "beta"], [0.001 * k, -0.002 * k], [], [0.5 * k, 1.0])


def torque(k: int) -> bytes:
    return encode_float64_multi_array(
        [("joint:alpha,beta", 2, 2), (f"stamp_ns:{k * 1_000_000}", 1, 1)], [float(k), -float(k)]
    )


def _rosbags(typename: str, **fields: Any) -> bytes:
    cls = TYPESTORE.types[typename]
    return bytes(TYPESTORE.serialize_cdr(cls(**fields), typename))


def clock(k: int) -> bytes:
    time = TYPESTORE.types["builtin_interfaces/msg/Time"](sec=k, nanosec=0)
    return _rosbags("rosgraph_msgs/msg/Clock", clock=time)


def diagnostics(k: int) -> bytes:
    types = TYPESTORE.types
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=k, nanosec=1), frame_id=""
    )
    status = types["diagnostic_msgs/msg/DiagnosticStatus"](
        level=b"\x00"[0],
        name="recorder",
        message="ok",
        hardware_id="",
        values=[types["diagnostic_msgs/msg/KeyValue"](key="written", value=str(k))],
    )
    return _rosbags("diagnostic_msgs/msg/DiagnosticArray", header=header, status=[status])


def log(k: int) -> bytes:
    types = TYPESTORE.types
    return _rosbags(
        "rcl_interfaces/msg/Log",
        stamp=types["builtin_interfaces/msg/Time"](sec=k, nanosec=0),
        level=20,
        name="node",
        msg=f"message {k}",
        file="f.py",
        function="f",
        line=k,
    )


def parameter_event(k: int) -> bytes:
    types = TYPESTORE.types
    return _rosbags(
        "rcl_interfaces/msg/ParameterEvent",
        stamp=types["builtin_interfaces/msg/Time"](sec=k, nanosec=0),
        node="/smm/controller_node",
        new_parameters=[],
        changed_parameters=[],
        deleted_parameters=[],
    )


def gain_event(stamp_ns: int, node: str = "/smm/controller_node", name: str = "fpdeso.robust_gain") -> bytes:
    """A ParameterEvent (CDR) changing ``name`` of ``node`` (a double array) at ``stamp_ns``."""
    types = TYPESTORE.types
    value = types["rcl_interfaces/msg/ParameterValue"](
        type=8,
        bool_value=False,
        integer_value=0,
        double_value=0.0,
        string_value="",
        byte_array_value=np.array([], dtype=np.uint8),
        bool_array_value=np.array([], dtype=np.bool_),
        integer_array_value=np.array([], dtype=np.int64),
        double_array_value=np.array([1.0, 1.0]),
        string_array_value=[],
    )
    event = types["rcl_interfaces/msg/ParameterEvent"](
        stamp=types["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9),
        node=node,
        new_parameters=[],
        changed_parameters=[types["rcl_interfaces/msg/Parameter"](name=name, value=value)],
        deleted_parameters=[],
    )
    return bytes(TYPESTORE.serialize_cdr(event, "rcl_interfaces/msg/ParameterEvent"))


TOPICS: dict[str, tuple[str, Any]] = {
    "/smm/joint_states": ("sensor_msgs/msg/JointState", joint_state),
    "/smm/torque_command": ("std_msgs/msg/Float64MultiArray", torque),
    "/clock": ("rosgraph_msgs/msg/Clock", clock),
    "/diagnostics": ("diagnostic_msgs/msg/DiagnosticArray", diagnostics),
    "/rosout": ("rcl_interfaces/msg/Log", log),
    "/parameter_events": ("rcl_interfaces/msg/ParameterEvent", parameter_event),
}


def rosbags_messages(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    """Topic -> [(log time, decoded message)] through rosbags' AnyReader."""
    found: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([bag], default_typestore=TYPESTORE) as reader:
        for connection, timestamp, raw in reader.messages():
            found.setdefault(connection.topic, []).append(
                (timestamp, reader.deserialize(raw, connection.msgtype))
            )
    return found


def mcap_messages(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    """Topic -> [(log time, decoded message)] through mcap + mcap-ros2-support, file after file."""
    found: dict[str, list[tuple[int, Any]]] = {}
    for path in sorted(bag.glob("*.mcap"), key=lambda p: int(p.stem.rsplit("_", 1)[1])):
        with path.open("rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            for _, channel, message, decoded in reader.iter_decoded_messages():
                found.setdefault(channel.topic, []).append((message.log_time, decoded))
    return found


def iter_mcap_files(bag: Path) -> Iterator[Path]:
    yield from sorted(bag.glob("*.mcap"))


def as_array(values: Any) -> np.ndarray:
    return np.asarray(list(values), dtype=np.float64)


def reference(k: int) -> bytes:
    dims = [("order:position,velocity,acceleration", 3, 6), ("joint:alpha,beta", 2, 2)]
    return encode_float64_multi_array(
        [*dims, (f"stamp_ns:{k * 1_000_000}", 1, 1)], [0.01 * k, 0.0, 0, 0, 0, 0]
    )


# ----------------------------------------------------------------- damaged bags (a good bag, then one damage)


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


DAMAGES: list[tuple[str, Callable[[Path], None], type[Exception], int]] = [
    ("no metadata.yaml", no_metadata, NotABagError, EXIT_NOT_A_BAG),
    ("truncated file", truncate, TruncatedBagError, EXIT_TRUNCATED),
    ("bad magic", bad_magic, CorruptBagError, EXIT_CORRUPT),
    ("counts disagree", wrong_count, CorruptBagError, EXIT_CORRUPT),
    ("metadata not YAML", garbage_metadata, CorruptBagError, EXIT_CORRUPT),
    ("metadata without version", metadata_without_version, CorruptBagError, EXIT_CORRUPT),
    ("storage file missing", missing_file, CorruptBagError, EXIT_CORRUPT),
]


def rewrite_bag(source: Path, target: Path, change: Callable[[BagMessage], bytes | None]) -> None:
    """Copies ``source`` into a new bag ``target`` with the project's writer; ``change`` gives each
    message's new CDR bytes, or None to drop it (a topic whose every message is dropped is dropped too)."""
    with BagReader(source) as reader:
        kept = [(message, change(message)) for message in reader.messages()]
        emptied = {message.topic for message, _ in kept}
        emptied -= {message.topic for message, data in kept if data is not None}
        with BagWriter(target) as writer:
            for topic in reader.metadata.topics:
                if topic.name not in emptied:
                    writer.create_topic(topic.name, topic.type, topic.offered_qos_profiles)
            for key, value in reader.metadata.custom_data.items():
                writer.set_custom_data(key, value)
            for message, data in kept:
                if data is not None:
                    writer.write(message.topic, data, message.log_time_ns, message.publish_time_ns)
