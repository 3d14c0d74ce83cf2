"""``smm-bag play``: publishes a bag's messages (raw CDR) with their original timing and offered QoS.

The schedule is the log times: message i goes out at ``start + (t_i - t_first - offset) / rate``. Options:
rate factor, loop, start offset, topic filter, remapping ``old:=new``, and ``/clock`` from the bag's time
(published every ``clock_period`` while playing, the bag's own ``/clock`` messages are then skipped).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from smm_bag.errors import MissingTopicsError, UnknownTypeError
from smm_bag.metadata import TopicInfo, service_event
from smm_bag.qos import QosProfile
from smm_bag.reader import BagReader

__all__ = ["PlayOptions", "PlayResult", "parse_remaps", "play"]


@dataclass(frozen=True)
class PlayOptions:
    """What ``smm-bag play`` does.

    Attributes:
        rate: Speed factor (> 0; 2 = twice as fast).
        loop: Start again at the end until stopped.
        start_offset_s: Skip this much of the bag's beginning (s), >= 0.
        topics: Topics to play (empty = all).
        remaps: ``{recorded topic: published topic}``.
        clock: Publish ``/clock`` from the bag's log time.
        clock_period_s: Period of that ``/clock`` (s).
        wait_for_subscribers_s: Before playing, wait up to this long until every topic has a subscriber.
    """

    rate: float = 1.0
    loop: bool = False
    start_offset_s: float = 0.0
    topics: tuple[str, ...] = ()
    remaps: Mapping[str, str] = field(default_factory=dict)
    clock: bool = False
    clock_period_s: float = 0.01
    wait_for_subscribers_s: float = 0.0

    def __post_init__(self) -> None:
        if not self.rate > 0.0:
            raise ValueError(f"rate must be > 0, got {self.rate!r}")
        if self.start_offset_s < 0.0:
            raise ValueError(f"start offset must be >= 0 s, got {self.start_offset_s!r}")
        if not self.clock_period_s > 0.0:
            raise ValueError(f"clock period must be > 0 s, got {self.clock_period_s!r}")


@dataclass(frozen=True)
class PlayResult:
    """Messages published per (published) topic, how often the bag was played, topics skipped and why."""

    published: Mapping[str, int]
    passes: int
    skipped: Mapping[str, str] = field(default_factory=dict)


def parse_remaps(items: Sequence[str]) -> dict[str, str]:
    """``["/a:=/b", ...]`` -> ``{"/a": "/b"}``.

    Raises:
        ValueError: An item is not ``old:=new`` with absolute names.
    """
    remaps = {}
    for item in items:
        old, separator, new = item.partition(":=")
        if not separator or not old.startswith("/") or not new.startswith("/"):
            raise ValueError(f"remap {item!r} must be /old:=/new")
        remaps[old] = new
    return remaps


def rclpy_qos(profiles: Sequence[QosProfile]) -> Any:
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415

    profile = profiles[0] if profiles else QosProfile()
    reliable = all(p.reliability != "best_effort" for p in profiles) if profiles else True
    transient = bool(profiles) and all(p.durability == "transient_local" for p in profiles)
    return QoSProfile(  # type: ignore[no-untyped-call,unused-ignore]
        history=HistoryPolicy.KEEP_LAST,
        depth=max(profile.depth, 10) if profile.history != "keep_all" else 1000,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE,
    )


def playable(topic: TopicInfo) -> tuple[Any, str]:
    """The message class of a topic, or None and why it cannot be played (as ``ros2 bag play`` skips it)."""
    from smm_bag.recorder_node import message_class  # noqa: PLC0415

    if service_event(topic.name, topic.type) is not None:
        return None, "service events are not played (ros2 bag play without --publish-service-requests)"
    if topic.serialization_format != "cdr":
        return None, f"serialization format {topic.serialization_format!r} is not CDR"
    try:
        return message_class(topic.type), ""
    except UnknownTypeError as error:
        return None, str(error)


def play(
    bag: Path,
    node: Any,
    options: PlayOptions,
    *,
    should_stop: Callable[[], bool] = lambda: False,
    progress: Callable[[int, int], None] | None = None,
    warn: Callable[[str], None] | None = None,
) -> PlayResult:
    """Publishes the bag through ``node`` (an rclpy node); returns what was published.

    Topics that cannot be played (type not installed, not CDR, service events) are skipped, each with one
    call of ``warn``, and listed in the result.

    Raises:
        BagError: The bag cannot be read.
        MissingTopicsError: A requested topic is not in the bag.
    """
    from rosgraph_msgs.msg import Clock  # noqa: PLC0415

    with BagReader(bag) as reader:
        available = {topic.name: topic for topic in reader.metadata.topics if topic.message_count > 0}
        chosen = list(options.topics) or list(available)
        missing = [topic for topic in chosen if topic not in available]
        if missing:
            raise MissingTopicsError(f"{bag} has no messages on {', '.join(missing)}")
        if options.clock:
            chosen = [topic for topic in chosen if topic != "/clock"]
        classes = {topic: playable(available[topic]) for topic in chosen}
        skipped = {topic: why for topic, (kind, why) in classes.items() if kind is None}
        for topic, why in skipped.items():
            if warn is not None:
                warn(f"skipping {topic}: {why}")
        chosen = [topic for topic in chosen if topic not in skipped]
        publishers = {
            topic: node.create_publisher(
                classes[topic][0],
                options.remaps.get(topic, topic),
                rclpy_qos(available[topic].offered_qos_profiles),
            )
            for topic in chosen
        }
        clock_publisher = node.create_publisher(Clock, "/clock", 10) if options.clock else None
        if options.wait_for_subscribers_s > 0:
            deadline = time.monotonic() + options.wait_for_subscribers_s
            while time.monotonic() < deadline and any(
                p.get_subscription_count() == 0 for p in publishers.values()
            ):
                time.sleep(0.01)
        total = sum(available[topic].message_count for topic in chosen)
        published: dict[str, int] = {options.remaps.get(topic, topic): 0 for topic in chosen}
        passes = 0
        first_ns = reader.metadata.starting_time_ns + round(options.start_offset_s * 1e9)
        while True:
            passes += 1
            start = time.monotonic_ns()
            next_clock = start
            sent = 0
            for message in reader.messages(chosen):
                if message.log_time_ns < first_ns:
                    continue
                due = start + round((message.log_time_ns - first_ns) / options.rate)
                while True:
                    now = time.monotonic_ns()
                    if clock_publisher is not None and now >= next_clock:
                        bag_time = first_ns + round((now - start) * options.rate)
                        stamp = Clock()
                        stamp.clock.sec, stamp.clock.nanosec = divmod(bag_time, 1_000_000_000)
                        clock_publisher.publish(stamp)
                        next_clock = now + round(options.clock_period_s * 1e9)
                    if now >= due or should_stop():
                        break
                    time.sleep(min(due - now, max(next_clock - now, 0) or due - now) / 1e9)
                if should_stop():
                    return PlayResult(published, passes, skipped)
                publishers[message.topic].publish(message.data)
                published[options.remaps.get(message.topic, message.topic)] += 1
                sent += 1
                if progress is not None and sent % 1000 == 0:
                    progress(sent, total)
            if progress is not None:
                progress(sent, total)
            if not options.loop or should_stop():
                return PlayResult(published, passes, skipped)
