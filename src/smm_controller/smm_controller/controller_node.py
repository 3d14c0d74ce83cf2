"""``controller_node``: the control law (FPDESO or a baseline) on the matched inputs of each stamp.

Publishes ``torque_command`` ([tau_alpha, tau_beta] N m) and ``controller_internals``, stamped with the
measurement's stamp. ``chain: internal`` runs the whole :class:`smm_controller.chain.ControlChain` on
``joint_states``; ``reference_source: internal`` samples the reference in the node. Inputs, parameters, live
retuning and the guarded ``algorithm`` switch: docs/NODES.md, "controller_node".
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Final, Protocol, Unpack

import numpy as np
import numpy.typing as npt
from rclpy.publisher import Publisher
from sensor_msgs.msg import JointState
from smm_msgs_py.conversions import (
    internals_to_msg,
    joint_state_to_sample,
    msg_to_labelled,
    msg_to_reference,
    reference_to_msg,
    torque_to_msg,
)
from smm_msgs_py.errors import InterfaceError
from smm_msgs_py.layouts import DISTURBANCE_ESTIMATE_ROWS
from smm_msgs_py.qos import qos_for_topic, subscription_qos_for_topic
from smm_node_runtime.parameters import ConfigParameters
from smm_schema.ranges import at_least, check_bounds
from std_msgs.msg import Float64MultiArray

from smm_controller.chain import ControlChain, JointController
from smm_controller.core import ControllerCore, CoreSettings, Refusal, StepResult
from smm_controller.fleso import FLESOConfig
from smm_controller.fleso_node import FLESO_PREFIX, MODEL_PREFIX
from smm_controller.laws import law_names, law_table
from smm_controller.limits import MeasurementLimits, OutputLimitConfig, OutputLimiter
from smm_controller.reference_node import ReferenceParameters
from smm_controller.sync import ExactTimeSynchronizer, Matched
from smm_controller.td import TrackingDifferentiatorConfig
from smm_controller.td_node import MEASUREMENT_PREFIX, TD_PREFIX, check_filter_factor
from smm_dynamics import SMMParameters
from smm_msgs_py import topics
from smm_node_runtime import (
    Admission,
    MeasurementDrivenNode,
    NodeOptions,
    Output,
    node_main,
    values_of,
)

__all__ = [
    "CHAIN_MODES",
    "DEFAULT_SWITCH_IDLE_TIME",
    "FLESO_PREFIX",
    "MEASUREMENT_PREFIX",
    "MODEL_PREFIX",
    "NODE_NAME",
    "OUTPUT_PREFIX",
    "REFERENCE_PREFIX",
    "REFERENCE_SOURCES",
    "TD_PREFIX",
    "ChainPlacement",
    "ControllerNode",
    "ControllerSelection",
    "ReferenceSource",
    "main",
]

NODE_NAME: Final[str] = "controller_node"
OUTPUT_PREFIX: Final[str] = "output"
"""Parameters of :class:`~smm_controller.limits.OutputLimitConfig` are ``output.<field>``."""

REFERENCE_PREFIX: Final[str] = "reference"
"""Prefix of the reference generator parameters (``reference.kind``, ``reference.sine.*``) when the node
samples the reference itself."""
DEFAULT_SWITCH_IDLE_TIME: Final[float] = 0.5
"""Default quiet time before ``algorithm`` may change (s)."""
CHAIN_MODES: Final[tuple[str, ...]] = ("external", "internal")
"""Values of the ``chain`` parameter."""
REFERENCE_SOURCES: Final[tuple[str, ...]] = ("topic", "internal")
"""Values of the ``reference_source`` parameter."""

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ControllerSelection:
    """Which control law runs, and when it may change.

    Attributes:
        algorithm: Control law, a name of :func:`smm_controller.laws.law_table`; its gains are the
            parameters ``<algorithm>.<field>``.
        switch_idle_time: A change of ``algorithm`` is accepted only when no input arrived during the last
            this many seconds of wall-clock time (s), >= 0; 0 accepts it at any time.
    """

    algorithm: str = "fpdeso"
    switch_idle_time: float = field(default=DEFAULT_SWITCH_IDLE_TIME, metadata=at_least(0.0))

    def __post_init__(self) -> None:
        if self.algorithm not in law_table():
            raise ValueError(f"algorithm must be one of {law_names()}, got {self.algorithm!r}")
        check_bounds(self)


@dataclass(frozen=True)
class ChainPlacement:
    """Where the TD and the FLESO run (declared read-only: the node's inputs depend on it).

    Attributes:
        chain: ``"external"``: in ``td_node`` and ``fleso_node``; this node reads ``joint_states_filtered``
            and ``disturbance_estimate``. ``"internal"``: in this node, on ``joint_states``.
    """

    chain: str = "external"

    def __post_init__(self) -> None:
        if self.chain not in CHAIN_MODES:
            raise ValueError(f"chain must be one of {CHAIN_MODES}, got {self.chain!r}")


@dataclass(frozen=True)
class ReferenceSource:
    """Where the reference comes from (declared read-only: the node's inputs depend on it).

    Attributes:
        reference_source: ``"topic"``: the ``reference`` topic, matched by stamp. ``"internal"``: sampled
            by this node from its ``reference.*`` parameters.
    """

    reference_source: str = "topic"

    def __post_init__(self) -> None:
        if self.reference_source not in REFERENCE_SOURCES:
            raise ValueError(
                f"reference_source must be one of {REFERENCE_SOURCES}, got {self.reference_source!r}"
            )


class ChangeSink(Protocol):
    """Where a loop that steps the core itself takes the core's parameter changes (applied between ticks)."""

    def put(self, change: Callable[[], None]) -> None:
        """Hands over one validated change."""


class ControllerNode(MeasurementDrivenNode):
    """Controller node: ROS glue around :class:`~smm_controller.core.ControllerCore`.

    Args:
        changes: A loop that steps :attr:`core` itself (the direct loop): the parameter changes (the
            core's, ``stamp.*``) are handed to it, and the node takes no ``joint_states``. None: changes
            apply at once.
        **options: The node options every SMM node takes (:class:`~smm_node_runtime.NodeOptions`).

    Raises:
        ValueError: invalid initial parameters (message names the parameter).
    """

    NODE_NAME = NODE_NAME

    def __init__(self, changes: ChangeSink | None = None, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        self._changes = changes
        self.last_input_s: float | None = None
        """Monotonic time of the last input (s), None before any (an ``algorithm`` switch waits for quiet)."""
        self.placement = ConfigParameters(self, "", ChainPlacement(), read_only=True)
        self.reference_source = ConfigParameters(self, "", ReferenceSource(), read_only=True)
        internal = self.reference_source.config.reference_source == "internal"
        self.reference: ReferenceParameters | None = (
            ReferenceParameters(self, REFERENCE_PREFIX) if internal else None
        )
        """The reference generator this node samples with ``reference_source = internal`` (else None)."""
        self.selection = ConfigParameters(
            self, "", ControllerSelection(), check=self._check_selection, on_change=self._on_selection
        )
        self.law_parameters: dict[str, ConfigParameters[Any]] = {
            name: ConfigParameters(self, name, law.config(), on_change=self._on_gains(name))
            for name, law in law_table().items()
        }
        # The laws that use a model (FPDESO) and, in the internal chain, the FLESO use the nominal model.
        self.model_parameters = ConfigParameters(
            self, MODEL_PREFIX, SMMParameters(), on_change=self._to_core("set_model")
        )
        self.output_limits = ConfigParameters(
            self, OUTPUT_PREFIX, OutputLimitConfig(), on_change=self._to_core("set_output_limits")
        )
        self.internal_chain = self.placement.config.chain == "internal"
        td, fleso, limits = TrackingDifferentiatorConfig(), FLESOConfig(), MeasurementLimits()
        if self.internal_chain:
            self.measurement_limits = ConfigParameters(
                self,
                MEASUREMENT_PREFIX,
                MeasurementLimits(),
                on_change=self._to_core("set_measurement_limits"),
            )
            self.td_parameters = ConfigParameters(
                self,
                TD_PREFIX,
                TrackingDifferentiatorConfig(),
                check=lambda config: check_filter_factor(config, self.control_period),
                on_change=self._to_core("set_td"),
            )
            self.fleso_parameters = ConfigParameters(
                self, FLESO_PREFIX, FLESOConfig(), on_change=self._to_core("set_fleso")
            )
            td, fleso = self.td_parameters.config, self.fleso_parameters.config
            limits = self.measurement_limits.config
        reference = self.reference
        self.core = ControllerCore(
            CoreSettings(
                algorithm=self.selection.config.algorithm,
                gains={name: parameters.config for name, parameters in self.law_parameters.items()},
                model=self.model_parameters.config,
                output_limits=self.output_limits.config,
                control_period=self.control_period,
                chain=self.internal_chain,
                td=td,
                fleso=fleso,
                measurement_limits=limits,
            ),
            self.admission,
            reference=None if reference is None else lambda: reference.generator,
            announce=self.get_logger().info,  # type: ignore[no-untyped-call]
        )
        """What the node does per measurement, without ROS."""
        self.sync: ExactTimeSynchronizer[Any] = ExactTimeSynchronizer(self._inputs())
        self.torque_publisher = self.create_publisher(
            Float64MultiArray, topics.TORQUE_COMMAND, qos_for_topic(topics.TORQUE_COMMAND)
        )
        self.internals_publisher = self.create_publisher(
            Float64MultiArray, topics.CONTROLLER_INTERNALS, qos_for_topic(topics.CONTROLLER_INTERNALS)
        )
        self.reference_publisher: Publisher | None = None
        """Publishes the sampled reference (``reference_source = internal``), else None."""
        if self.internal_reference:
            self.reference_publisher = self.create_publisher(
                Float64MultiArray, topics.REFERENCE, qos_for_topic(topics.REFERENCE)
            )
        else:
            self.create_subscription(
                Float64MultiArray,
                topics.REFERENCE,
                self._on_reference,
                subscription_qos_for_topic(topics.REFERENCE),
            )
        if self.internal_chain:
            if changes is not None:  # the loop hands the core its measurements
                return
            self.create_subscription(
                JointState,
                topics.JOINT_STATES,
                self._on_measurement,
                subscription_qos_for_topic(topics.JOINT_STATES),
            )
            return
        self.create_subscription(
            JointState,
            topics.JOINT_STATES_FILTERED,
            self._on_filtered,
            subscription_qos_for_topic(topics.JOINT_STATES_FILTERED),
        )
        self.create_subscription(
            Float64MultiArray,
            topics.DISTURBANCE_ESTIMATE,
            self._on_disturbance_estimate,
            subscription_qos_for_topic(topics.DISTURBANCE_ESTIMATE),
        )

    @property
    def algorithm(self) -> str:
        """Name of the running law."""
        return self.core.algorithm

    @property
    def controller(self) -> JointController:
        """The running law."""
        return self.core.law

    @property
    def chain(self) -> ControlChain | None:
        """The TD -> FLESO -> law chain this node runs with ``chain = internal`` (None otherwise)."""
        return self.core.chain

    @property
    def limiter(self) -> OutputLimiter:
        """Torque and rate limits after the law."""
        return self.core.limiter

    @property
    def internal_reference(self) -> bool:
        """True with ``reference_source = internal``: this node samples the reference, nothing feeds it."""
        return self.reference is not None

    # ------------------------------------------------------------------------------ laws and switching

    def _inputs(self) -> tuple[str, ...]:
        reference = () if self.internal_reference else (topics.REFERENCE,)
        if self.internal_chain:
            return (topics.JOINT_STATES, *reference)
        required = (topics.JOINT_STATES_FILTERED, *reference)
        if self.core.uses_disturbance_estimate:
            return (*required, topics.DISTURBANCE_ESTIMATE)
        return required

    def _check_selection(self, candidate: ControllerSelection) -> None:
        last = self.last_input_s
        if last is None:  # nothing received yet (and, at start-up, no core yet)
            return
        reason = self.core.switch_refusal(
            candidate.algorithm, candidate.switch_idle_time, time.monotonic() - last
        )
        if reason is not None:
            raise ValueError(reason)

    def _apply(self, change: Callable[[], None]) -> None:
        """A parameter change (the core's, ``stamp.*``): at once, or handed to the loop stepping the core."""
        if self._changes is None:
            change()
        else:
            self._changes.put(change)

    def _on_selection(self, selection: ControllerSelection) -> None:
        def switch() -> None:
            if selection.algorithm != self.core.algorithm:
                self.core.switch(selection.algorithm)
                self.sync.set_inputs(self._inputs())

        self._apply(switch)

    def _on_gains(self, name: str) -> Callable[[Any], None]:
        # In place, so that the PID keeps its integrator (a rebuild would be a torque step under load).
        # A law that is not running takes its current gains when a switch builds it.
        return lambda config: self._apply(lambda: self.core.set_gains(name, config))

    def _to_core(self, setter: str) -> Callable[[Any], None]:
        """Hands a parameter group's new config to the core's ``setter`` (the core is built after them)."""

        def forward(config: Any) -> None:
            self._apply(lambda: getattr(self.core, setter)(config))

        return forward

    # --------------------------------------------------------------------------------------- inputs

    def _on_measurement(self, msg: JointState) -> None:
        """The fused chain's input: one admission path, :meth:`ControllerCore.measurement`.

        As in the direct loop; with ``reference_source = topic`` matched by stamp with it (:attr:`sync`).
        """
        if self.reference is None:
            self._on_input(topics.JOINT_STATES, msg, joint_state_to_sample)
            return
        self.last_input_s = time.monotonic()
        try:
            sample = joint_state_to_sample(msg)
        except InterfaceError as error:
            self.reject(topics.JOINT_STATES, error)
            return
        started = time.perf_counter()
        position, effort = sample.position, sample.effort
        result = self.core.measurement(
            topics.JOINT_STATES,
            sample.stamp_ns,
            (float(position[0]), float(position[1])),
            None if effort is None else (float(effort[0]), float(effort[1])),
            self.get_clock().now().nanoseconds,
        )
        if time.perf_counter() - started > self.control_period:
            self.counters.deadline_misses += 1
        self.publish_result(result)

    def publish_result(self, result: StepResult) -> None:
        """Publishes what answers a measurement stepped by :meth:`ControllerCore.measurement`.

        Warnings, ``torque_command``, then ``controller_internals`` and ``reference`` while someone
        subscribes (a recorder, a plot); a re-sent stamp gets its torque again, nothing else.
        """
        if isinstance(result, Refusal):
            if result.counter != "duplicates_answered":
                self.warn_refused(result.topic, result.counter, result.message)
            return
        if result.verdict.admission is Admission.RESYNC:
            self.report(topics.JOINT_STATES, result.verdict)
            self.diagnostics.check()
        self.torque_publisher.publish(torque_to_msg(np.array(result.torque), result.stamp_ns))
        if result.duplicate or not self.diagnostics_observed():
            return
        for publisher, message in self.diagnostics_of(result.stamp_ns):
            publisher.publish(message)

    def _on_filtered(self, msg: JointState) -> None:
        self._on_input(
            topics.JOINT_STATES_FILTERED, msg, lambda m: joint_state_to_sample(m, require_velocity=True)
        )

    def _on_reference(self, msg: Float64MultiArray) -> None:
        self._on_input(topics.REFERENCE, msg, msg_to_reference)

    def _on_disturbance_estimate(self, msg: Float64MultiArray) -> None:
        if topics.DISTURBANCE_ESTIMATE in self.sync.inputs:
            self._on_input(
                topics.DISTURBANCE_ESTIMATE,
                msg,
                lambda m: msg_to_labelled(m, expected_rows=DISTURBANCE_ESTIMATE_ROWS),
            )

    def _on_input(self, topic: str, msg: Any, parse: Callable[[Any], Any]) -> None:
        self.last_input_s = time.monotonic()
        try:
            item = parse(msg)
        except InterfaceError as error:
            self.reject(topic, error)
            return
        self.take_input(topic, item, values_of(item))

    def take_input(self, topic: str, item: Any, values: object) -> None:
        """Admits a parsed input (``values`` as :func:`values_of` gives them); steps once it is matched."""
        if not self.admit(topic, item.stamp_ns, values):
            return
        if topic == topics.JOINT_STATES:
            position = (float(item.position[0]), float(item.position[1]))
            refused = self.core.implausible(topic, item.stamp_ns, position)
            if refused is not None:
                self.warn_refused(topic, refused.counter, refused.message)
                return
        matched = self.sync.add(topic, item.stamp_ns, item)
        self.counters.dropped_unmatched = self.sync.dropped
        if matched is not None:
            stamp_ns = matched.stamp_ns
            self.answer(stamp_ns, lambda: self._step(matched), lambda: self.diagnostics_of(stamp_ns))

    # ----------------------------------------------------------------------------------------- step

    def _reference_rows(self, matched: Matched[Any]) -> Sequence[Sequence[float]]:
        """The reference of the matched stamp, 3x2 floats: the input's, or sampled (``internal``)."""
        if self.reference is None:
            rows: list[list[float]] = matched.items[topics.REFERENCE].values.tolist()
            return rows
        return self.core.reference_rows(matched.stamp_ns)

    def _step(self, matched: Matched[Any]) -> list[Output]:
        reference = self._reference_rows(matched)
        # The conversions validated shapes and finiteness, so the chain's float path skips the checks
        # of ControlChain.step (same arithmetic, same result).
        if self.internal_chain:
            measurement = matched.items[topics.JOINT_STATES]
            effort = measurement.effort
            torque = self.core.step(
                matched.stamp_ns,
                (float(measurement.position[0]), float(measurement.position[1])),
                None if effort is None else (float(effort[0]), float(effort[1])),
                reference,
            )
            return [self.torque_output(torque, matched.stamp_ns)]  # raises for a non-finite torque
        filtered = matched.items[topics.JOINT_STATES_FILTERED]
        estimate = matched.items.get(topics.DISTURBANCE_ESTIMATE)
        xi: FloatArray = np.zeros(2) if estimate is None else estimate.values[0]
        observer = estimate is not None and self.controller.velocity_source == "observer"
        velocity = estimate.values[1] if estimate is not None and observer else filtered.velocity
        limited = self.core.step_law(
            (float(filtered.position[0]), float(filtered.position[1])),
            (float(velocity[0]), float(velocity[1])),
            (float(xi[0]), float(xi[1])),
            reference,
        )
        return [self.torque_output(limited, matched.stamp_ns)]

    def torque_output(self, torque: tuple[float, float], stamp_ns: int) -> Output:
        """The ``torque_command`` output of a step (N m, shape (2,)).

        Raises:
            InterfaceError: The torque is not finite (the step then gives no output).
        """
        return (self.torque_publisher, torque_to_msg(np.array(torque), stamp_ns))

    def diagnostics_of(self, stamp_ns: int) -> list[Output]:
        """``controller_internals`` (and the sampled ``reference``) of the step that answered ``stamp_ns``."""
        outputs = [(self.internals_publisher, internals_to_msg(self.core.internals_rows(), stamp_ns))]
        if self.reference_publisher is not None:
            outputs.append(
                (self.reference_publisher, reference_to_msg(self.core.last_reference_array(), stamp_ns))
            )
        return outputs

    def diagnostics_observed(self) -> bool:
        """True while ``controller_internals`` or the sampled ``reference`` has a subscriber."""
        publishers = [self.internals_publisher, self.reference_publisher]
        return any(p is not None and p.get_subscription_count() > 0 for p in publishers)

    def on_time_jump(self, *, backward: bool) -> None:
        """Forget the old timeline's pending stamps; a new run (backward jump) starts from fresh state."""
        self.sync.clear()
        if backward:
            self.core.reset()

    def health_counts(self) -> dict[str, int]:
        """The base counts plus ``clamps`` (steps whose torque the output limits changed)."""
        return {**super().health_counts(), "clamps": self.limiter.clamps}

    def health_warnings(self) -> tuple[str, ...]:
        """A clamp within the period makes the status WARN."""
        return (*super().health_warnings(), "clamps")


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``controller_node``: exit status 0 after Ctrl-C/SIGTERM, 2 for invalid parameters."""
    return node_main(lambda context: ControllerNode(context=context), args, node=ControllerNode.NODE_NAME)


if __name__ == "__main__":
    sys.exit(main())
