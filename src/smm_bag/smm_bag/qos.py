"""Offered QoS profiles as rosbag2 writes them: version 9 policy names, version <= 8 rmw enum integers.

Policies are kept as names; the integer of a policy is its index in the rmw enum (rmw/types.h, Jazzy).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import yaml

from smm_bag.errors import CorruptBagError

__all__ = ["INFINITE_NS", "QosProfile", "dump_profiles", "load_profiles", "profiles_from_rclpy"]

INFINITE_NS = 9_223_372_036_854_775_807
"""RMW_DURATION_INFINITE: sec 9223372036, nsec 854775807."""

_NS = 1_000_000_000
_HISTORY = ("system_default", "keep_last", "keep_all", "unknown")
_RELIABILITY = ("system_default", "reliable", "best_effort", "unknown", "best_available")
_DURABILITY = ("system_default", "transient_local", "volatile", "unknown", "best_available")
_LIVELINESS = (
    "system_default",
    "automatic",
    "manual_by_node",
    "manual_by_topic",
    "unknown",
    "best_available",
)
_FOXY_INFINITE = ((0x7FFFFFFF, 0xFFFFFFFF), (0x7FFFFFFF, 0x7FFFFFFF))
"""Infinite durations of Foxy-era RMWs, read as infinite (rosbag2_storage qos.cpp does the same)."""


@dataclass(frozen=True)
class QosProfile:
    """One offered QoS profile (durations in ns; ``INFINITE_NS`` = unlimited)."""

    history: str = "keep_last"
    depth: int = 10
    reliability: str = "reliable"
    durability: str = "volatile"
    deadline_ns: int = INFINITE_NS
    lifespan_ns: int = INFINITE_NS
    liveliness: str = "automatic"
    liveliness_lease_duration_ns: int = INFINITE_NS
    avoid_ros_namespace_conventions: bool = False

    def __post_init__(self) -> None:
        for name, value, allowed in (
            ("history", self.history, _HISTORY),
            ("reliability", self.reliability, _RELIABILITY),
            ("durability", self.durability, _DURABILITY),
            ("liveliness", self.liveliness, _LIVELINESS),
        ):
            if value not in allowed:
                raise CorruptBagError(f"QoS {name} {value!r} is not one of {', '.join(allowed)}")
        for name in ("depth", "deadline_ns", "lifespan_ns", "liveliness_lease_duration_ns"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise CorruptBagError(f"QoS {name} must be an integer >= 0, got {value!r}")

    def to_yaml_node(self, version: int = 9) -> dict[str, Any]:
        """The mapping rosbag2 writes for this profile in metadata ``version`` (<= 8: enum integers)."""

        def policy(value: str, allowed: Sequence[str]) -> str | int:
            return value if version >= 9 else allowed.index(value)

        return {
            "history": policy(self.history, _HISTORY),
            "depth": self.depth,
            "reliability": policy(self.reliability, _RELIABILITY),
            "durability": policy(self.durability, _DURABILITY),
            "deadline": _duration(self.deadline_ns),
            "lifespan": _duration(self.lifespan_ns),
            "liveliness": policy(self.liveliness, _LIVELINESS),
            "liveliness_lease_duration": _duration(self.liveliness_lease_duration_ns),
            "avoid_ros_namespace_conventions": self.avoid_ros_namespace_conventions,
        }

    @classmethod
    def from_yaml_node(cls, node: Mapping[str, Any]) -> QosProfile:
        """Parses one profile (version 9 names; version <= 8 integers are mapped to names).

        Raises:
            CorruptBagError: A field is missing or invalid.
        """
        if not isinstance(node, Mapping):
            raise CorruptBagError(f"invalid QoS profile {node!r}: not a mapping")
        try:
            return cls(
                history=_policy(node["history"], _HISTORY),
                depth=int(node.get("depth", 0)),
                reliability=_policy(node["reliability"], _RELIABILITY),
                durability=_policy(node["durability"], _DURABILITY),
                deadline_ns=_parse_duration(node.get("deadline")),
                lifespan_ns=_parse_duration(node.get("lifespan")),
                liveliness=_policy(node["liveliness"], _LIVELINESS),
                liveliness_lease_duration_ns=_parse_duration(node.get("liveliness_lease_duration")),
                avoid_ros_namespace_conventions=bool(node.get("avoid_ros_namespace_conventions", False)),
            )
        except (KeyError, TypeError, ValueError) as error:
            if isinstance(error, CorruptBagError):
                raise
            raise CorruptBagError(f"invalid QoS profile {dict(node)!r}: {error}") from None

    def as_dict(self) -> dict[str, Any]:
        """Plain field mapping (for JSON)."""
        return asdict(self)


def _duration(ns: int) -> dict[str, int]:
    return {"sec": ns // _NS, "nsec": ns % _NS}


def _parse_duration(node: Any) -> int:
    if node is None:
        return INFINITE_NS
    if (int(node["sec"]), int(node["nsec"])) in _FOXY_INFINITE:
        return INFINITE_NS
    return min(int(node["sec"]) * _NS + int(node["nsec"]), INFINITE_NS)


def _policy(value: Any, allowed: Sequence[str]) -> str:
    if isinstance(value, int) and not isinstance(value, bool):
        if 0 <= value < len(allowed):
            return allowed[value]
        raise CorruptBagError(f"QoS policy {value} out of range")
    return str(value)


def dump_profiles(profiles: Sequence[QosProfile], version: int = 9) -> str:
    """The YAML string of an MCAP channel's ``offered_qos_profiles`` (and of metadata.yaml version <= 8)."""
    return str(yaml.safe_dump([profile.to_yaml_node(version) for profile in profiles], sort_keys=False))


def load_profiles(node: Any) -> list[QosProfile]:
    """Profiles from a YAML string (channel metadata, version <= 8 metadata.yaml) or a parsed list.

    Raises:
        CorruptBagError: Not a list of profiles.
    """
    if isinstance(node, str):
        if not node.strip():
            return []
        try:
            node = yaml.safe_load(node)
        except yaml.YAMLError as error:
            raise CorruptBagError(f"offered_qos_profiles is not YAML: {error}") from None
    if node is None:
        return []
    if not isinstance(node, list):
        raise CorruptBagError(f"offered_qos_profiles must be a list, got {type(node).__name__}")
    return [QosProfile.from_yaml_node(item) for item in node]


def profiles_from_rclpy(profiles: Sequence[Any]) -> list[QosProfile]:
    """Converts rclpy ``QoSProfile`` objects (e.g. from ``get_publishers_info_by_topic``)."""
    result = []
    for profile in profiles:

        def ns(duration: Any) -> int:
            value = int(duration.nanoseconds)
            return min(max(value, 0), INFINITE_NS)

        result.append(
            QosProfile(
                history=profile.history.name.lower(),
                depth=int(profile.depth),
                reliability=profile.reliability.name.lower(),
                durability=profile.durability.name.lower(),
                deadline_ns=ns(profile.deadline),
                lifespan_ns=ns(profile.lifespan),
                liveliness=profile.liveliness.name.lower(),
                liveliness_lease_duration_ns=ns(profile.liveliness_lease_duration),
                avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
            )
        )
    return result
