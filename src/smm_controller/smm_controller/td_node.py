"""``td_node``: the tracking differentiator (:mod:`smm_controller.td`) on the raw measurement.

Subscribes ``joint_states`` (raw measurement, position in rad); for each new stamp steps the TD once with
dt = ``control_period`` and publishes ``joint_states_filtered`` (position x1 in rad, velocity x2 in rad/s,
``header.stamp`` = the measurement's) and ``~/internals`` (TD internals + the node counters). Stamp policy,
bad input and parameters: see ``docs/NODES.md`` and :mod:`smm_node_runtime`.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Unpack

from sensor_msgs.msg import JointState
from smm_msgs_py.conversions import (
    JointSample,
    internals_to_msg,
    joint_state_to_sample,
    sample_to_joint_state,
)
from smm_msgs_py.errors import InterfaceError
from smm_msgs_py.qos import diagnostic_qos, qos_for_topic, subscription_qos_for_topic
from smm_node_runtime.parameters import ConfigParameters
from std_msgs.msg import Float64MultiArray

from smm_controller.limits import MeasurementLimits, PlausibilityCheck
from smm_controller.td import TrackingDifferentiator, TrackingDifferentiatorConfig
from smm_msgs_py import topics
from smm_node_runtime import (
    MeasurementDrivenNode,
    NodeOptions,
    Output,
    node_main,
    values_of,
)

__all__ = [
    "INTERNALS_TOPIC",
    "MEASUREMENT_PREFIX",
    "NODE_NAME",
    "TD_PREFIX",
    "TdNode",
    "check_filter_factor",
    "main",
]

NODE_NAME = "td_node"
MEASUREMENT_PREFIX = "measurement"
"""Parameters of :class:`~smm_controller.limits.MeasurementLimits` are ``measurement.<field>``."""
TD_PREFIX = "td"
"""Parameters of :class:`~smm_controller.td.TrackingDifferentiatorConfig` are ``td.<field>``."""
INTERNALS_TOPIC = "~/internals"
"""Private diagnostics topic: TD internals (x1, x2, input) and node counters, labelled rows."""


def check_filter_factor(config: TrackingDifferentiatorConfig, control_period: float) -> None:
    """Refuse TD gains whose filter factor h is below the node's step: the TD needs h >= dt.

    Args:
        config: Proposed TD parameters.
        control_period: The node's control period dt (s).

    Raises:
        ValueError: naming the parameter ``td.filter_factor`` and both values.
    """
    if min(config.filter_factor) < control_period:
        raise ValueError(
            f"{TD_PREFIX}.filter_factor {config.filter_factor!r} must be >= control_period = "
            f"{control_period!r} s"
        )


class TdNode(MeasurementDrivenNode):
    """Tracking differentiator node.

    Args:
        **options: The node options every SMM node takes (:class:`~smm_node_runtime.NodeOptions`).

    Raises:
        ValueError: invalid initial parameters (message names the parameter).
    """

    NODE_NAME = NODE_NAME

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        self.td_parameters = ConfigParameters(
            self,
            TD_PREFIX,
            TrackingDifferentiatorConfig(),
            check=self._check_td_config,
            on_change=self._on_td_config,
        )
        self.td = TrackingDifferentiator(self.td_parameters.config)
        self.measurement_limits = ConfigParameters(
            self, MEASUREMENT_PREFIX, MeasurementLimits(), on_change=self._on_measurement_limits
        )
        self.plausibility = PlausibilityCheck(self.measurement_limits.config)
        self._filtered_publisher = self.create_publisher(
            JointState, topics.JOINT_STATES_FILTERED, qos_for_topic(topics.JOINT_STATES_FILTERED)
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

    def _check_td_config(self, config: TrackingDifferentiatorConfig) -> None:
        check_filter_factor(config, self.timing.config.control_period)

    def _on_td_config(self, config: TrackingDifferentiatorConfig) -> None:
        # Same TD, new gains from the next sample: x1 and x2 carry on (no velocity restart from 0).
        self.td.reconfigure(config)

    def on_time_jump(self, *, backward: bool) -> None:
        """A new run (backward jump) starts from a fresh TD and no previous position."""
        if backward:
            self.td.reset()
            self.plausibility.reset()

    def _on_measurement_limits(self, limits: MeasurementLimits) -> None:
        self.plausibility.reconfigure(limits)

    def _on_measurement(self, msg: JointState) -> None:
        try:
            sample = joint_state_to_sample(msg)
        except InterfaceError as error:
            self.reject(topics.JOINT_STATES, error)
            return
        stamp_ns = sample.stamp_ns
        if self.admit(topics.JOINT_STATES, stamp_ns, values_of(sample)):
            position = (float(sample.position[0]), float(sample.position[1]))
            reason = self.plausibility.admit(position, stamp_ns, self.period_ns)
            if reason is not None:
                self.reject_implausible(topics.JOINT_STATES, stamp_ns, reason)
                return
            self.answer(stamp_ns, lambda: self._step(sample), lambda: self._diagnostics(stamp_ns))

    def _step(self, sample: JointSample) -> list[Output]:
        position, velocity = self.td.step(sample.position, self.control_period)
        filtered = JointSample(sample.stamp_ns, position, velocity)
        return [(self._filtered_publisher, sample_to_joint_state(filtered))]

    def _diagnostics(self, stamp_ns: int) -> list[Output]:
        rows = {**self.td.internals, **self.counter_rows()}
        return [(self._internals_publisher, internals_to_msg(rows, stamp_ns))]


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``td_node``: exit status 0 after Ctrl-C/SIGTERM, 2 for invalid parameters."""
    return node_main(lambda context: TdNode(context=context), args, node=TdNode.NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
