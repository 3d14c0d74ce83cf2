"""``recorder_node``: records the stack's topics raw (serialized CDR) to a rosbag2 MCAP bag.

Services (std_srvs/Trigger) ``~/pause``, ``~/resume``, ``~/split``; writes what is still queued on
SIGINT/SIGTERM; loss accounting on ``/diagnostics``, in the log and in the bag. QoS, receive times and
start gates: docs/BAGS.md, "recorder_node" and "What it adds to rosbag2".
"""

from __future__ import annotations

import array
import datetime
import importlib
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import yaml
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.parameter import parameter_value_to_python
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.subscription import Subscription
from smm_msgs_py.qos import qos_for_topic
from smm_node_runtime.node import NodeOptions
from smm_schema.ranges import above, at_least, bounds, check_bounds
from std_srvs.srv import Trigger

from smm_bag.errors import UnknownTypeError
from smm_bag.manifest import RunManifest, git_describe
from smm_bag.qos import QosProfile, profiles_from_rclpy
from smm_bag.writer import BagWriter, WriterOptions
from smm_msgs_py import topics as stack
from smm_node_runtime import ConfigParameters, DiagnosticsPublisher, Health, Level, SmmNode, node_main

__all__ = [
    "DEFAULT_EXTRA_TOPICS",
    "PUBLISHERS_FILE",
    "RecorderConfig",
    "RecorderNode",
    "default_topics",
    "main",
]

PUBLISHERS_FILE = ".publishers"
"""File in the bag folder: ``topic count`` per line, the publishers each recording subscription has matched
(read by smm-launch, which starts the plant once every controller-side publisher is matched)."""
DEFAULT_EXTRA_TOPICS = ("/clock", "/diagnostics", "/parameter_events", "/rosout")
_STAMPED = ("joint_states", "ground_truth", "reference", "torque_command", stack.CLOCK)


def message_class(type_name: str) -> Any:
    """The Python class of ``pkg/msg/Type`` (what rosidl_runtime_py's get_message does).

    Raises:
        UnknownTypeError: Not a ``pkg/msg/Type`` name, or the type is not installed.
    """
    package, separator, name = type_name.partition("/msg/")
    if not separator or not package or not name:
        raise UnknownTypeError(f"{type_name!r} is not a message type (pkg/msg/Type)")
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError):
        raise UnknownTypeError(f"message type {type_name} is not installed") from None


def default_topics(namespace: str = stack.DEFAULT_NAMESPACE) -> tuple[str, ...]:
    """Every stack topic under ``namespace``, then /clock, /diagnostics, /parameter_events, /rosout."""
    names = [stack.fully_qualified(topic, namespace) for topic in stack.ALL_TOPICS if topic != stack.CLOCK]
    return (*names, *DEFAULT_EXTRA_TOPICS)


@dataclass(frozen=True)
class RecorderConfig:
    """Parameters of ``recorder_node`` (read-only after start).

    Attributes:
        output: Bag folder to create ("" = ``bags/run_<UTC time>``); must not exist.
        topics: Comma-separated absolute topic names ("" = every stack topic and /clock, /diagnostics,
            /parameter_events, /rosout).
        stack_namespace: Namespace of the stack's relative topics.
        max_duration: Split after this many seconds of messages (s); 0 = never.
        max_size: Split when a file reaches this many bytes; 0 = never, else >= 65536 (64 KiB).
        compression: ``none`` or ``zstd`` (MCAP chunk compression).
        flush_interval: Longest time between flushes to the OS (s), in (0, 1]: what a kill can cost.
        discovery_period: How often topics without a known type are looked up in the graph (s).
        scenario: Scenario name for the manifest.
        seed: Noise seed for the manifest (-1 = none).
        plant: ``sim`` or ``hardware`` (manifest).
        controller: Controller name (manifest).
        clock_mode: ``lockstep`` or ``realtime`` (manifest).
        control_period: Control period (s); the stamp-gap check expects this spacing.
        queue_depth: Messages each subscription queues while the recorder's executor is behind (a stall
            longer than depth x period loses the oldest). Its memory is kept at its high-water mark:
            docs/BAGS.md, "Memory of a long recording".
    """

    output: str = ""
    topics: str = ""
    stack_namespace: str = stack.DEFAULT_NAMESPACE
    max_duration: float = field(default=0.0, metadata=at_least(0.0))
    max_size: int = field(default=0, metadata=at_least(0))
    compression: Literal["none", "zstd"] = "none"
    flush_interval: float = field(default=0.5, metadata=bounds(0.0, 1.0, low_open=True))
    discovery_period: float = field(default=0.2, metadata=above(0.0))
    scenario: str = ""
    seed: int = field(default=-1, metadata=at_least(-1))
    plant: Literal["", "sim", "hardware"] = ""
    controller: str = ""
    clock_mode: str = ""
    control_period: float = field(default=0.001, metadata=above(0.0))
    queue_depth: int = field(default=10_000, metadata=bounds(1, 1_000_000))

    def __post_init__(self) -> None:
        check_bounds(self)
        if 0 < self.max_size < 65536:
            raise ValueError(f"max_size must be 0 (never split) or >= 65536 bytes, got {self.max_size}")
        for name in self.topic_list:
            if not name.startswith("/"):
                raise ValueError(f"topics must be absolute names, got {name!r}")

    @property
    def topic_list(self) -> tuple[str, ...]:
        """The topics to record."""
        if not self.topics.strip():
            return default_topics(self.stack_namespace)
        return tuple(dict.fromkeys(name.strip() for name in self.topics.split(",") if name.strip()))


class RecorderNode(SmmNode):
    """Records topics to a bag; see the module docstring."""

    NODE_NAME = "recorder_node"

    def __init__(self, **options: Any) -> None:
        typed: NodeOptions = options  # type: ignore[assignment]
        super().__init__(**typed)
        self.settings = ConfigParameters(self, "", RecorderConfig(), read_only=True)
        config = self.settings.config
        output = Path(config.output or f"bags/run_{datetime.datetime.now(datetime.UTC):%Y%m%d_%H%M%S}")
        self.manifest = RunManifest(
            version=git_describe(),
            scenario=config.scenario,
            seed=None if config.seed < 0 else config.seed,
            plant=config.plant,
            controller=config.controller,
            control_period_ns=round(config.control_period * 1e9),
            clock_mode=config.clock_mode,
            namespace=config.stack_namespace,
        )
        stamped = frozenset(stack.fully_qualified(name, config.stack_namespace) for name in _STAMPED)
        self.writer = BagWriter(
            output,
            WriterOptions(
                max_duration_ns=round(config.max_duration * 1e9),
                max_size_bytes=config.max_size,
                compression=config.compression,
                flush_interval_ns=round(config.flush_interval * 1e9),
                custom_data=self.manifest.to_custom_data(),
                period_ns=self.manifest.control_period_ns,
                stamped_topics=stamped,
            ),
        )
        self.paused = False
        self._recorded: dict[str, tuple[Subscription, str]] = {}
        self._pending = list(config.topic_list)
        self._skipped: dict[str, str] = {}
        self._seen: list[str] = []
        self._asked: set[str] = set()
        self._waiting: dict[str, Any] = {}
        self._node_parameters: dict[str, dict[str, Any]] = {}
        self._discover()
        self._discovery_timer = self.create_timer(config.discovery_period, self._discover)
        self._flush_timer = self.create_timer(min(config.flush_interval, 0.1), self.writer.tick)
        self.create_service(Trigger, "~/pause", self._on_pause)
        self.create_service(Trigger, "~/resume", self._on_resume)
        self.create_service(Trigger, "~/split", self._on_split)
        self.diagnostics = DiagnosticsPublisher(self, self.health)
        self.get_logger().info(  # type: ignore[no-untyped-call]
            f"recording {len(config.topic_list)} topics to {output}"
        )

    # -- subscriptions -----------------------------------------------------------------------------------
    def _discover(self) -> None:
        self._write_seen()
        self._ask_parameters()
        still = []
        for topic in self._pending:
            infos = self.get_publishers_info_by_topic(topic)
            type_name = infos[0].topic_type if infos else self._known_type(topic)
            if type_name is None:
                still.append(topic)
                continue
            try:
                self._subscribe(topic, type_name, [info.qos_profile for info in infos])
            except UnknownTypeError as error:
                self._skip(topic, type_name, error)
        self._pending = still

    def _skip(self, topic: str, type_name: str, why: UnknownTypeError) -> None:
        """A topic whose type is not installed here: one warning, named in the manifest (as play skips)."""
        self._skipped[topic] = type_name
        self.get_logger().warning(f"skipping {topic}: {why}")  # type: ignore[no-untyped-call]
        self.writer.set_custom_data("smm.topics_skipped", yaml.safe_dump(self._skipped, sort_keys=True))

    def _ask_parameters(self) -> None:
        """Asks every node that appeared for all its parameters (once), for the manifest.

        One client per node, kept until its service is ready: creating and destroying endpoints at every
        tick would flood discovery and delay the matching of the topics being recorded.
        """
        me = self.get_fully_qualified_name()
        for name, namespace in self.get_node_names_and_namespaces():
            node = f"{namespace.rstrip('/')}/{name}"
            if node in self._asked or node == me:
                continue
            client = self._waiting.get(node)
            if client is None:
                client = self._waiting[node] = self.create_client(ListParameters, f"{node}/list_parameters")
            if not client.service_is_ready():
                continue  # asked again at the next discovery tick
            del self._waiting[node]
            self._asked.add(node)
            future = client.call_async(ListParameters.Request())
            future.add_done_callback(lambda done, node=node, client=client: self._on_list(node, client, done))

    def _on_list(self, node: str, client: Any, done: Any) -> None:
        self.destroy_client(client)
        result = done.result()
        if result is None:
            return
        names = list(result.result.names)
        getter = self.create_client(GetParameters, f"{node}/get_parameters")
        request = GetParameters.Request()
        request.names = names
        future = getter.call_async(request)
        future.add_done_callback(  # type: ignore[no-untyped-call]
            lambda got, node=node, names=names, getter=getter: self._on_get(node, names, getter, got)
        )

    def _on_get(self, node: str, names: list[str], client: Any, done: Any) -> None:
        self.destroy_client(client)
        result = done.result()
        if result is None or self.writer.closed:
            return
        values = {}
        for name, value in zip(names, result.values, strict=False):
            python = parameter_value_to_python(value)
            values[name] = list(python) if isinstance(python, (list, tuple, array.array)) else python
        self._node_parameters[node] = values
        self.writer.set_custom_data("smm.parameters", yaml.safe_dump(self._node_parameters, sort_keys=True))

    def _write_seen(self) -> None:
        """``<bag>/.publishers``: ``topic count``, matched publishers per recorded topic (for smm-launch)."""
        seen = sorted(
            f"{topic} {count}"
            for topic, (subscription, _) in self._recorded.items()
            if (count := subscription.get_publisher_count()) > 0
        )
        if seen != self._seen:
            self._seen = seen
            marker = self.writer.path / PUBLISHERS_FILE
            temporary = marker.with_suffix(".tmp")
            temporary.write_text("".join(f"{line}\n" for line in seen))
            temporary.replace(marker)

    def _known_type(self, topic: str) -> str | None:
        namespace = self.settings.config.stack_namespace
        for relative, message_type in stack.TOPIC_TYPES.items():
            if stack.fully_qualified(relative, namespace) == topic:
                module = message_type.__module__.split(".")[0]
                return f"{module}/msg/{message_type.__name__}"
        known = {
            "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
            "/parameter_events": "rcl_interfaces/msg/ParameterEvent",
            "/rosout": "rcl_interfaces/msg/Log",
        }
        return known.get(topic)

    def _subscribe(self, topic: str, type_name: str, offered: Sequence[Any]) -> None:
        reliable = all(profile.reliability == ReliabilityPolicy.RELIABLE for profile in offered)
        # TRANSIENT_LOCAL where every publisher offers it (the stack's do): matched late, the recorder still
        # gets what the writer sent before, from its history. Requested from a VOLATILE writer, it would not
        # match at all, so other topics stay VOLATILE.
        durable = (
            all(profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for profile in offered)
            if offered
            else self._stack_depth(topic) is not None
        )
        qos = QoSProfile(  # type: ignore[no-untyped-call,unused-ignore]
            history=HistoryPolicy.KEEP_LAST,
            depth=self.settings.config.queue_depth,
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE,
        )
        message_type = message_class(type_name)

        # One argument: the stack's EventsExecutor cannot pass message info, so the receive time is taken
        # here (within the callback's latency of the middleware's receive time).
        def on_message(data: bytes) -> None:
            self._record(topic, data, None)

        subscription = self.create_subscription(message_type, topic, on_message, qos, raw=True)
        self._recorded[topic] = (subscription, type_name)

    def _ensure_topic(self, topic: str) -> None:
        if topic in self.writer.topics:
            return
        _, type_name = self._recorded[topic]
        offered = profiles_from_rclpy([info.qos_profile for info in self.get_publishers_info_by_topic(topic)])
        depth = self._stack_depth(topic)
        if depth is not None:
            # Discovery does not carry history and depth (rosbag2 stores "unknown", 0); the stack's QoS
            # table knows them for its own topics, which lets a replay offer the same profile.
            offered = [
                replace(profile, history="keep_last", depth=depth)
                if profile.history == "unknown"
                else profile
                for profile in offered
            ]
        self.writer.create_topic(topic, type_name, offered or [QosProfile()])

    def _stack_depth(self, topic: str) -> int | None:
        namespace = self.settings.config.stack_namespace
        for relative in stack.ALL_TOPICS:
            if stack.fully_qualified(relative, namespace) == topic:
                return int(qos_for_topic(relative).depth)
        return None

    def _record(self, topic: str, data: bytes, info: Any) -> None:
        if self.writer.closed:
            return
        self.writer.loss.received(topic)
        if self.paused:
            self.writer.loss.received(topic, -1)  # paused: not counted as received-and-lost
            return
        received = int(info.get("received_timestamp") or 0) if isinstance(info, dict) else 0
        source = int(info.get("source_timestamp") or 0) if isinstance(info, dict) else 0
        now = received if received > 0 else time.time_ns()
        self._ensure_topic(topic)
        self.writer.write(topic, bytes(data), now, source if source > 0 else now, count_received=False)

    # -- services ----------------------------------------------------------------------------------------
    def _on_pause(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.paused = True
        response.success, response.message = True, "paused"
        return response

    def _on_resume(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.paused = False
        response.success, response.message = True, "recording"
        return response

    def _on_split(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.writer.split()
        response.success = True
        response.message = f"now writing {self.writer.metadata.relative_file_paths[-1]}"
        return response

    # -- health and shutdown -----------------------------------------------------------------------------
    def health(self) -> Health:
        """Loss accounting as a diagnostics status (ERROR if anything received was not written)."""
        loss = self.writer.loss
        lost, missing = loss.total_lost, loss.total_missing
        level = Level.ERROR if lost else Level.WARN if missing or self._pending else Level.OK
        message = (
            f"{lost} messages lost"
            if lost
            else f"{missing} samples missing in stamps"
            if missing
            else f"waiting for publishers of {', '.join(self._pending)}"
            if self._pending
            else "paused"
            if self.paused
            else "recording"
        )
        values: dict[str, object] = {"bag": str(self.writer.path), "flushed": self.writer.flushed_count}
        for topic, counters in loss.as_dict().items():
            values[f"{topic} received/written/gaps"] = (
                f"{counters['received']}/{counters['written']}/{counters['stamp_gaps']}"
            )
        return Health(level, message, values)

    def drain(self) -> int:
        """Takes and writes every message still queued in the middleware; returns how many."""
        taken = 0
        for topic, (subscription, _) in self._recorded.items():
            while True:
                try:
                    with subscription.handle:
                        item = subscription.handle.take_message(subscription.msg_type, subscription.raw)
                except Exception:
                    break
                if item is None:
                    break
                self._record(topic, item[0], item[1] if len(item) > 1 else None)
                taken += 1
        return taken

    def close(self) -> None:
        """Drains the queues, closes the bag and logs the loss report."""
        if self.writer.closed:
            return
        drained = self.drain()
        logger = self.get_logger()  # type: ignore[no-untyped-call]
        unread = sorted((self._asked | set(self._waiting)) - set(self._node_parameters))
        if unread:  # said, not left out silently
            self.writer.set_custom_data("smm.parameters_unread", yaml.safe_dump(unread))
            logger.warning(
                f"the manifest has no parameters of {', '.join(unread)}: no answer from the parameter "
                "service while recording (the node ended first, or does not spin)"
            )
        metadata = self.writer.close()
        (self.writer.path / PUBLISHERS_FILE).unlink(missing_ok=True)
        logger.info(
            f"closed {self.writer.path}: {metadata.message_count} messages ({drained} taken at shutdown), "
            f"{self.writer.loss.total_lost} lost, {self.writer.loss.total_missing} samples missing in stamps"
        )
        for line in self.writer.loss.summary_lines():
            logger.info(line)
        if self._skipped:
            skipped = ", ".join(sorted(self._skipped))
            logger.warning(f"{len(self._skipped)} topics skipped (type not installed): {skipped}")

    def destroy_node(self) -> None:
        """Closes the bag cleanly, then destroys the node."""
        self.close()
        super().destroy_node()  # type: ignore[no-untyped-call]


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``recorder_node``: exit 0 after SIGINT/SIGTERM (bag closed), 2 for bad parameters."""
    return node_main(lambda context: RecorderNode(context=context), args, node=RecorderNode.NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
