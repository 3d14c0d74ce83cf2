"""``reference_node``: the reference trajectory (:mod:`smm_controller.reference`) sampled at each measurement.

For each new ``joint_states`` stamp s publishes ``reference`` (3x2: rad, rad/s, rad/s^2; columns alpha, beta)
for the stamp s + ``lookahead`` control periods, at t = (that stamp - first stamp) / 1e9 s, so it waits at
the controller when that measurement arrives. Parameters (``kind``, ``<kind>.<field>``, ``lookahead``) and
why one period ahead: docs/NODES.md, "reference_node".
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Unpack

import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import JointState
from smm_msgs_py.conversions import (
    internals_to_msg,
    joint_state_to_sample,
    reference_to_msg,
)
from smm_msgs_py.errors import InterfaceError
from smm_msgs_py.qos import diagnostic_qos, qos_for_topic, subscription_qos_for_topic
from smm_node_runtime.parameters import ConfigParameters
from smm_schema.fields import parameter_name
from smm_schema.ranges import at_least, check_bounds
from std_msgs.msg import Float64MultiArray

from smm_controller.reference import REFERENCE_KINDS, ReferenceClock, ReferenceGenerator
from smm_msgs_py import topics
from smm_node_runtime import (
    MeasurementDrivenNode,
    NodeOptions,
    Output,
    node_main,
)

__all__ = [
    "DEFAULT_LOOKAHEAD",
    "INTERNALS_TOPIC",
    "NODE_NAME",
    "ReferenceLookahead",
    "ReferenceNode",
    "ReferenceParameters",
    "ReferenceSelection",
    "main",
]

NODE_NAME = "reference_node"
INTERNALS_TOPIC = "~/internals"
"""Private diagnostics topic: row ``time`` (s) and the node counters."""
DEFAULT_LOOKAHEAD = 1
"""Default number of control periods the published reference is ahead of the measurement that triggers it."""


@dataclass(frozen=True)
class ReferenceSelection:
    """Which reference generator the node samples.

    Attributes:
        kind: "step", "sine", "ramp_hold" or "excite"; its fields are the parameters ``<kind>.<field>``.
    """

    kind: str = "sine"

    def __post_init__(self) -> None:
        if self.kind not in REFERENCE_KINDS:
            raise ValueError(f"kind must be one of {sorted(REFERENCE_KINDS)}, got {self.kind!r}")


@dataclass(frozen=True)
class ReferenceLookahead:
    """How far ahead of each measurement the reference is published (declared read-only).

    Attributes:
        lookahead: Number of control periods, an int >= 0. 0 publishes the reference of the measurement's
            own stamp, so the controller waits for one more hop (measurement -> reference node ->
            controller) in every step; 1 (default) publishes it one step early.
    """

    lookahead: int = field(default=DEFAULT_LOOKAHEAD, metadata=at_least(0))

    def __post_init__(self) -> None:
        check_bounds(self)


class ReferenceParameters:
    """A reference generator held as node parameters: ``<prefix>.kind`` and ``<prefix>.<kind>.<field>``.

    Declares :class:`ReferenceSelection` and every generator's fields (validated and applied live like any
    config); :attr:`generator` is the one ``kind`` selects, with its current parameters. Shared by
    ``reference_node`` (no prefix) and ``controller_node`` (prefix ``reference``, when it samples the
    reference itself), so the two sample the same function of time from the same parameters.

    Args:
        node: The node declaring the parameters.
        prefix: Parameter name prefix without trailing dot (``""`` for none).
    """

    def __init__(self, node: Node, prefix: str = "") -> None:
        self.selection = ConfigParameters(node, prefix, ReferenceSelection())
        self.generators: dict[str, ConfigParameters[ReferenceGenerator]] = {
            kind: ConfigParameters(node, parameter_name(prefix, kind), factory())
            for kind, factory in REFERENCE_KINDS.items()
        }

    @property
    def generator(self) -> ReferenceGenerator:
        """The generator ``kind`` selects, with its current parameters."""
        return self.generators[self.selection.config.kind].config


class ReferenceNode(MeasurementDrivenNode):
    """Reference generator node.

    Args:
        **options: The node options every SMM node takes (:class:`~smm_node_runtime.NodeOptions`).

    Raises:
        ValueError: invalid initial parameters (message names the parameter).
    """

    NODE_NAME = NODE_NAME

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        self.lookahead = ConfigParameters(self, "", ReferenceLookahead(), read_only=True)
        self.reference = ReferenceParameters(self)
        self.clock = ReferenceClock(self.get_logger().info)  # type: ignore[no-untyped-call]
        """Reference time from the stamps: t = 0 at the first answered measurement."""
        self._time_s = 0.0
        self._reference_publisher = self.create_publisher(
            Float64MultiArray, topics.REFERENCE, qos_for_topic(topics.REFERENCE)
        )
        self._internals_publisher = self.create_publisher(
            Float64MultiArray, INTERNALS_TOPIC, diagnostic_qos()
        )
        self.create_subscription(
            JointState,
            topics.JOINT_STATES,
            self._on_measurement,
            subscription_qos_for_topic(topics.JOINT_STATES),
        )

    @property
    def generator(self) -> ReferenceGenerator:
        """The generator sampled at the next measurement (per ``kind`` and its parameters)."""
        return self.reference.generator

    def _on_measurement(self, msg: JointState) -> None:
        try:
            stamp_ns = joint_state_to_sample(msg).stamp_ns
        except InterfaceError as error:
            self.reject(topics.JOINT_STATES, error)
            return
        if self.admit(topics.JOINT_STATES, stamp_ns):
            self.answer(stamp_ns, lambda: self._step(stamp_ns), lambda: self._diagnostics(stamp_ns))

    def on_time_jump(self, *, backward: bool) -> None:
        """A new run (backward jump) starts its reference at t = 0 again."""
        if backward:
            self.clock = ReferenceClock(self.get_logger().info)  # type: ignore[no-untyped-call]

    def _step(self, stamp_ns: int) -> list[Output]:
        ahead_ns = self.lookahead.config.lookahead * self.period_ns
        if self.clock.first_stamp_ns is None:
            stamps = range(stamp_ns, stamp_ns + ahead_ns + 1, self.period_ns)
        else:
            stamps = range(stamp_ns + ahead_ns, stamp_ns + ahead_ns + 1)
        generator = self.generator
        outputs: list[Output] = []
        for reference_stamp_ns in stamps:
            self._time_s = self.clock.time_s(reference_stamp_ns)
            reference = generator.evaluate(self._time_s)
            outputs.append((self._reference_publisher, reference_to_msg(reference, reference_stamp_ns)))
        return outputs

    def _diagnostics(self, stamp_ns: int) -> list[Output]:
        rows = {"time": np.full(2, self._time_s), **self.counter_rows()}
        return [(self._internals_publisher, internals_to_msg(rows, stamp_ns))]


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``reference_node``: exit status 0 after Ctrl-C/SIGTERM, 2 for invalid parameters."""
    return node_main(lambda context: ReferenceNode(context=context), args, node=ReferenceNode.NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
