"""``fleso_node``: the fuzzy linear extended state observer (:mod:`smm_controller.fleso`), once per stamp.

Matches ``joint_states_filtered`` (TD position, rad) and ``joint_states`` (applied torque, N m; without
effort, the previous stamp's ``torque_command``) by stamp; publishes ``disturbance_estimate`` (rows
``xi_tilde`` N m, ``x2_hat`` rad/s), ``observer_state`` and ``~/internals``. Parameters ``fleso.*`` and
``model.*``, and the applied-torque rule: docs/NODES.md, "fleso_node".
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from typing import Any, Final, Unpack

import numpy as np
import numpy.typing as npt
from sensor_msgs.msg import JointState
from smm_msgs_py.conversions import (
    JointSample,
    internals_to_msg,
    joint_state_to_sample,
    labelled_to_msg,
    msg_to_torque,
)
from smm_msgs_py.errors import InterfaceError
from smm_msgs_py.layouts import DISTURBANCE_ESTIMATE_ROWS, OBSERVER_STATE_ROWS
from smm_msgs_py.qos import diagnostic_qos, qos_for_topic, subscription_qos_for_topic
from smm_node_runtime.parameters import ConfigParameters
from std_msgs.msg import Float64MultiArray

from smm_controller.fleso import FLESO, FLESOConfig
from smm_controller.sync import DEFAULT_MAX_PENDING, ExactTimeSynchronizer, Matched
from smm_dynamics import SMMParameters
from smm_msgs_py import topics
from smm_node_runtime import (
    MeasurementDrivenNode,
    NodeOptions,
    Output,
    node_main,
    values_of,
)

FloatArray = npt.NDArray[np.float64]

__all__ = [
    "COMMANDS_KEPT",
    "COMMAND_FALLBACK_LATE_ROW",
    "FLESO_PREFIX",
    "INTERNALS_TOPIC",
    "MODEL_PREFIX",
    "NODE_NAME",
    "FlesoNode",
    "main",
]

NODE_NAME = "fleso_node"
FLESO_PREFIX = "fleso"
"""Parameters of :class:`~smm_controller.fleso.FLESOConfig` are ``fleso.<field>``."""
MODEL_PREFIX = "model"
"""Parameters of the nominal model :class:`smm_dynamics.SMMParameters` are ``model.<field>``."""
INTERNALS_TOPIC = "~/internals"
"""Private diagnostics topic: every FLESO internal and the node counters, labelled rows."""
COMMAND_FALLBACK_LATE_ROW: Final[str] = "command_fallback_late"
"""Counter row of ``~/internals``: steps without effort whose previous command had not arrived in time."""
COMMANDS_KEPT: Final[int] = DEFAULT_MAX_PENDING
"""Torque commands remembered (the newest stamps), for measurements without effort."""


class FlesoNode(MeasurementDrivenNode):
    """Disturbance observer node.

    Args:
        **options: The node options every SMM node takes (:class:`~smm_node_runtime.NodeOptions`).

    Raises:
        ValueError: invalid initial parameters (message names the parameter).
    """

    NODE_NAME = NODE_NAME

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        self.fleso_parameters = ConfigParameters(
            self, FLESO_PREFIX, FLESOConfig(), on_change=self._reconfigure
        )
        self.model_parameters = ConfigParameters(
            self, MODEL_PREFIX, SMMParameters(), on_change=self._reconfigure
        )
        self.fleso = FLESO(self.fleso_parameters.config, self.model_parameters.config)
        self.command_fallback_late = 0
        """Steps without effort whose previous command had not arrived (the newest one was used)."""
        self._commands: dict[int, FloatArray] = {}
        self.sync: ExactTimeSynchronizer[JointSample] = ExactTimeSynchronizer(
            (topics.JOINT_STATES_FILTERED, topics.JOINT_STATES)
        )
        self._estimate_publisher = self.create_publisher(
            Float64MultiArray, topics.DISTURBANCE_ESTIMATE, qos_for_topic(topics.DISTURBANCE_ESTIMATE)
        )
        self._observer_publisher = self.create_publisher(
            Float64MultiArray, topics.OBSERVER_STATE, qos_for_topic(topics.OBSERVER_STATE)
        )
        self._internals_publisher = self.create_publisher(
            Float64MultiArray, INTERNALS_TOPIC, diagnostic_qos()
        )
        self.create_subscription(
            JointState,
            topics.JOINT_STATES_FILTERED,
            self._on_filtered,
            subscription_qos_for_topic(topics.JOINT_STATES_FILTERED),
        )
        self.create_subscription(
            JointState,
            topics.JOINT_STATES,
            self._on_measurement,
            subscription_qos_for_topic(topics.JOINT_STATES),
        )
        self.create_subscription(
            Float64MultiArray,
            topics.TORQUE_COMMAND,
            self._on_command,
            subscription_qos_for_topic(topics.TORQUE_COMMAND),
        )

    @property
    def newest_command_stamp_ns(self) -> int | None:
        """Newest stamp (ns) among the torque commands held, None before the first."""
        return max(self._commands) if self._commands else None

    def _reconfigure(self, _config: Any) -> None:
        # Same observer, new gains/model from the next step: x^ and the estimate carry on (no bump).
        self.fleso.reconfigure(self.fleso_parameters.config, params=self.model_parameters.config)

    def _on_command(self, msg: Float64MultiArray) -> None:
        # Not subject to the stamp policy: a command answers a measurement this node has already answered.
        try:
            command = msg_to_torque(msg)
        except InterfaceError as error:
            self.reject(topics.TORQUE_COMMAND, error)
            return
        self._commands[command.stamp_ns] = command.values
        if len(self._commands) > COMMANDS_KEPT:
            del self._commands[min(self._commands)]

    def _commanded_torque(self, previous_stamp_ns: int | None) -> FloatArray:
        """Torque that acted since the measurement ``previous_stamp_ns`` (ns), from the commands."""
        if previous_stamp_ns is None:
            return np.zeros(2)
        command = self._commands.get(previous_stamp_ns)
        if command is not None:
            return command
        self.command_fallback_late += 1
        return self._commands[max(self._commands)] if self._commands else np.zeros(2)

    def _on_filtered(self, msg: JointState) -> None:
        self._on_input(topics.JOINT_STATES_FILTERED, msg)

    def on_time_jump(self, *, backward: bool) -> None:
        """Forget the old timeline's pending stamps and commands; a new run starts from a fresh observer."""
        self.sync.clear()
        self._commands.clear()
        if backward:
            self.fleso.reset()

    def _on_measurement(self, msg: JointState) -> None:
        self._on_input(topics.JOINT_STATES, msg)

    def _on_input(self, topic: str, msg: JointState) -> None:
        try:
            sample = joint_state_to_sample(msg)
        except InterfaceError as error:
            self.reject(topic, error)
            return
        if not self.admit(topic, sample.stamp_ns, values_of(sample)):
            return
        matched = self.sync.add(topic, sample.stamp_ns, sample)
        self.counters.dropped_unmatched = self.sync.dropped
        if matched is not None:
            stamp_ns = matched.stamp_ns
            previous_ns = self.last_answered_stamp_ns
            self.answer(
                stamp_ns, lambda: self._step(matched, previous_ns), lambda: self._diagnostics(stamp_ns)
            )

    def _step(self, matched: Matched[JointSample], previous_stamp_ns: int | None) -> list[Output]:
        position = matched.items[topics.JOINT_STATES_FILTERED].position
        effort = matched.items[topics.JOINT_STATES].effort
        applied_torque = effort if effort is not None else self._commanded_torque(previous_stamp_ns)
        estimate = self.fleso.step(position, applied_torque, self.control_period)
        rows = np.stack([estimate, self.fleso.velocity_floats()])
        message = labelled_to_msg(rows, DISTURBANCE_ESTIMATE_ROWS, matched.stamp_ns)
        return [(self._estimate_publisher, message)]

    def _diagnostics(self, stamp_ns: int) -> list[Output]:
        internals = self.fleso.internals
        observer = np.stack([internals[row] for row in OBSERVER_STATE_ROWS])
        return [
            (self._observer_publisher, labelled_to_msg(observer, OBSERVER_STATE_ROWS, stamp_ns)),
            (self._internals_publisher, internals_to_msg({**internals, **self.counter_rows()}, stamp_ns)),
        ]

    def counter_rows(self) -> Mapping[str, FloatArray]:
        """The common counters plus :data:`COMMAND_FALLBACK_LATE_ROW`, as internals rows."""
        late = np.full(2, float(self.command_fallback_late))
        return {**super().counter_rows(), COMMAND_FALLBACK_LATE_ROW: late}


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``fleso_node``: exit status 0 after Ctrl-C/SIGTERM, 2 for invalid parameters."""
    return node_main(lambda context: FlesoNode(context=context), args, node=FlesoNode.NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
