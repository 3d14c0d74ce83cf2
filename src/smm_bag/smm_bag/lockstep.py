"""``smm-bag play --lockstep``: replay a bag into a node one stamp at a time, waiting for its answer.

Each (topic, stamp) of the chosen stamped topics is published once, stamp by stamp; the player then waits
for the node's answer with that stamp on ``answer_topic`` or ``timeout_s`` (counted and reported). Why timed
replay cannot do this: docs/BAGS.md, "smm-bag".
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from smm_bag.cdr import stamp_of
from smm_bag.errors import BagError, MissingTopicsError
from smm_bag.player import rclpy_qos
from smm_bag.reader import BagReader

__all__ = ["LockstepOptions", "LockstepResult", "UnstampedTopicError", "play_lockstep"]

ANSWER_DEPTH = 1000
"""Depth of the player's subscription to the answers (none may be lost while it publishes)."""


class UnstampedTopicError(BagError):
    """A topic chosen for lockstep replay carries no stamp (only stamped topics can be played in lockstep)."""


@dataclass(frozen=True)
class LockstepOptions:
    """What ``smm-bag play --lockstep`` does.

    Attributes:
        answer_topic: Absolute topic of the node's answers (e.g. ``/smm/disturbance_estimate``).
        topics: Stamped topics to play (absolute, as recorded; empty = every stamped topic but the answer's).
        remaps: ``{recorded topic: published topic}``.
        timeout_s: Wait at most this long for each answer (s), > 0.
        wait_for_subscribers_s: Before playing, wait up to this long until every topic has a subscriber and
            the answer topic a publisher (s), >= 0.
    """

    answer_topic: str
    topics: tuple[str, ...] = ()
    remaps: Mapping[str, str] = field(default_factory=dict)
    timeout_s: float = 1.0
    wait_for_subscribers_s: float = 10.0

    def __post_init__(self) -> None:
        if not self.answer_topic.startswith("/"):
            raise ValueError(f"answer topic must be an absolute name, got {self.answer_topic!r}")
        if not self.timeout_s > 0.0:
            raise ValueError(f"answer timeout must be > 0 s, got {self.timeout_s!r}")
        if not self.wait_for_subscribers_s >= 0.0:
            raise ValueError(f"wait for subscribers must be >= 0 s, got {self.wait_for_subscribers_s!r}")


@dataclass(frozen=True)
class LockstepResult:
    """Messages published per (published) topic, stamps played, and the node's answers.

    Attributes:
        published: Messages published per topic.
        stamps: Stamps played, in order (ns).
        answers: The first answer received per stamp (CDR bytes).
        timeouts: Stamps whose answer did not come within the timeout, in order (ns).
    """

    published: Mapping[str, int]
    stamps: tuple[int, ...]
    answers: Mapping[int, bytes]
    timeouts: tuple[int, ...]


def _steps(reader: BagReader, chosen: list[str]) -> list[tuple[int, list[tuple[str, bytes]]]]:
    """``[(stamp, [(topic, data), ...]), ...]``: each (topic, stamp) once, stamps by first appearance."""
    types = reader.topics
    steps: dict[int, list[tuple[str, bytes]]] = {}
    seen: set[tuple[str, int]] = set()
    for message in reader.messages(chosen):
        stamp = stamp_of(types[message.topic], message.data)
        if stamp is None:
            raise UnstampedTopicError(f"{message.topic} ({types[message.topic]}) carries no stamp")
        if (message.topic, stamp) not in seen:
            seen.add((message.topic, stamp))
            steps.setdefault(stamp, []).append((message.topic, bytes(message.data)))
    return list(steps.items())


def play_lockstep(
    bag: Path,
    node: Any,
    executor: Any,
    options: LockstepOptions,
    *,
    should_stop: Callable[[], bool] = lambda: False,
    progress: Callable[[int, int], None] | None = None,
) -> LockstepResult:
    """Plays ``bag`` through ``node`` (rclpy, added to ``executor``, which this spins) stamp by stamp.

    Raises:
        BagError: The bag cannot be read.
        MissingTopicsError: A chosen topic or the answer topic's type is not in the bag.
        UnstampedTopicError: A chosen topic carries no stamp.
    """
    from smm_bag.recorder_node import message_class  # noqa: PLC0415

    with BagReader(bag) as reader:
        available = {topic.name: topic for topic in reader.metadata.topics if topic.message_count > 0}
        chosen = list(options.topics) or [t for t in available if t != options.answer_topic]
        missing = [t for t in (*chosen, options.answer_topic) if t not in available]
        if missing:
            raise MissingTopicsError(f"{bag} has no messages on {', '.join(missing)}")
        steps = _steps(reader, chosen)
        answer_type = available[options.answer_topic].type
    publishers = {
        topic: node.create_publisher(
            message_class(available[topic].type),
            options.remaps.get(topic, topic),
            rclpy_qos(available[topic].offered_qos_profiles),
        )
        for topic in chosen
    }
    answers: dict[int, bytes] = {}

    def on_answer(data: bytes) -> None:
        stamp = stamp_of(answer_type, data)
        if stamp is not None and stamp not in answers:
            answers[stamp] = bytes(data)

    answer_qos = rclpy_qos(available[options.answer_topic].offered_qos_profiles)
    answer_qos.depth = ANSWER_DEPTH
    subscription = node.create_subscription(
        message_class(answer_type), options.answer_topic, on_answer, answer_qos, raw=True
    )
    deadline = time.monotonic() + options.wait_for_subscribers_s
    while time.monotonic() < deadline and (
        any(p.get_subscription_count() == 0 for p in publishers.values())
        or subscription.get_publisher_count() == 0
    ):
        executor.spin_once(timeout_sec=0.01)
    published = {options.remaps.get(topic, topic): 0 for topic in chosen}
    played: list[int] = []
    timeouts: list[int] = []
    for index, (stamp, messages) in enumerate(steps):
        if should_stop():
            break
        for topic, data in messages:
            publishers[topic].publish(data)
            published[options.remaps.get(topic, topic)] += 1
        played.append(stamp)
        answer_deadline = time.monotonic() + options.timeout_s
        while stamp not in answers and time.monotonic() < answer_deadline and not should_stop():
            executor.spin_once(timeout_sec=0.005)
        if stamp not in answers:
            timeouts.append(stamp)
        if progress is not None and (index + 1) % 1000 == 0:
            progress(index + 1, len(steps))
    if progress is not None:
        progress(len(played), len(steps))
    for publisher in publishers.values():
        node.destroy_publisher(publisher)
    node.destroy_subscription(subscription)
    return LockstepResult(published, tuple(played), answers, tuple(timeouts))
