"""``controller_node``: the control law (FPDESO or a baseline) on the matched inputs of each stamp.

Publishes ``torque_command`` ([tau_alpha, tau_beta] N m) and ``controller_internals``, stamped with the
measurement's stamp. ``chain: internal`` runs the whole :class:`smm_controller.chain.ControlChain` on
``joint_states``; ``reference_source: internal`` samples the reference in the node. Inputs, parameters, live
retuning and the guarded ``algorithm`` switch: docs/NODES.md, "controller_node".
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, Final, Generic, TypeVar, Unpack

import numpy as np
import numpy.typing as npt
from sensor_msgs.msg import JointState
from smm_dynamics.validation import at_least, check_bounds
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
from std_msgs.msg import Float64MultiArray

from smm_controller.baselines import (
    FPDConfig,
    FPDController,
    NPDConfig,
    NPDController,
    PIDConfig,
    PIDController,
)
from smm_controller.chain import (
    CONTROLLER_NAMES,
    ControlChain,
    JointController,
    limited_torque,
    stage_internals,
)
from smm_controller.fleso import FLESO, FLESOConfig
from smm_controller.fleso_node import FLESO_PREFIX, MODEL_PREFIX
from smm_controller.fpdeso import FPDESOConfig, FPDESOController
from smm_controller.limits import (
    MeasurementLimits,
    OutputLimitConfig,
    OutputLimiter,
    PlausibilityCheck,
)
from smm_controller.reference_node import ReferenceClock, ReferenceParameters
from smm_controller.sync import ExactTimeSynchronizer, Matched
from smm_controller.td import TrackingDifferentiator, TrackingDifferentiatorConfig
from smm_controller.td_node import MEASUREMENT_PREFIX, TD_PREFIX, check_filter_factor
from smm_dynamics import SMMParameters
from smm_msgs_py import topics
from smm_node_runtime import (
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
ConfigT = TypeVar("ConfigT")
LawT = TypeVar("LawT", bound=JointController)


@dataclass(frozen=True)
class ControllerSelection:
    """Which control law runs, and when it may change.

    Attributes:
        algorithm: Control law, "fpdeso", "fpd", "pid" or "npd"; its gains are the parameters
            ``<algorithm>.<field>``.
        switch_idle_time: A change of ``algorithm`` is accepted only when no input arrived during the last
            this many seconds of wall-clock time (s), >= 0; 0 accepts it at any time.
    """

    algorithm: str = "fpdeso"
    switch_idle_time: float = field(default=DEFAULT_SWITCH_IDLE_TIME, metadata=at_least(0.0))

    def __post_init__(self) -> None:
        if self.algorithm not in CONTROLLER_NAMES:
            raise ValueError(f"algorithm must be one of {CONTROLLER_NAMES}, got {self.algorithm!r}")
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


@dataclass(frozen=True)
class _Law(Generic[ConfigT, LawT]):
    """A control law: its default gains, how to build it and how to give a running one new gains/model."""

    default: ConfigT
    build: Callable[[ConfigT, SMMParameters], LawT]
    reconfigure: Callable[[LawT, ConfigT, SMMParameters], None]
    uses_disturbance_estimate: bool = False


def _reconfigure_fpdeso(law: FPDESOController, config: FPDESOConfig, model: SMMParameters) -> None:
    law.reconfigure(config, params=model)


def _reconfigure_baseline(
    law: FPDController | PIDController | NPDController, config: Any, _model: SMMParameters
) -> None:
    law.reconfigure(config)  # the baselines use no model


_LAWS: Final[Mapping[str, _Law[Any, Any]]] = {
    "fpdeso": _Law(FPDESOConfig(), FPDESOController, _reconfigure_fpdeso, uses_disturbance_estimate=True),
    "fpd": _Law(FPDConfig(), lambda config, _model: FPDController(config), _reconfigure_baseline),
    "pid": _Law(PIDConfig(), lambda config, _model: PIDController(config), _reconfigure_baseline),
    "npd": _Law(NPDConfig(), lambda config, _model: NPDController(config), _reconfigure_baseline),
}


class ControllerNode(MeasurementDrivenNode):
    """Controller node.

    Args:
        **options: The node options every SMM node takes (:class:`~smm_node_runtime.NodeOptions`).

    Raises:
        ValueError: invalid initial parameters (message names the parameter).
    """

    NODE_NAME = NODE_NAME
    SUBSCRIBES_MEASUREMENT: ClassVar[bool] = True
    """False for a host that hands the internal chain its measurements itself (the direct loop)."""

    def __init__(self, **options: Unpack[NodeOptions]) -> None:
        super().__init__(**options)
        self._last_input_time: float | None = None
        self.placement = ConfigParameters(self, "", ChainPlacement(), read_only=True)
        self.reference_source = ConfigParameters(self, "", ReferenceSource(), read_only=True)
        internal = self.reference_source.config.reference_source == "internal"
        self.reference: ReferenceParameters | None = (
            ReferenceParameters(self, REFERENCE_PREFIX) if internal else None
        )
        """The reference generator this node samples with ``reference_source = internal`` (else None)."""
        self.reference_clock = ReferenceClock(self.get_logger().info)  # type: ignore[no-untyped-call]
        """Time of the sampled reference: t = 0 at the first matched measurement (``internal`` only)."""
        self.selection = ConfigParameters(
            self, "", ControllerSelection(), check=self._check_selection, on_change=self._on_selection
        )
        self.law_parameters: dict[str, ConfigParameters[Any]] = {
            name: ConfigParameters(self, name, law.default, on_change=self._on_gains(name))
            for name, law in _LAWS.items()
        }
        # FPDESO (and, in the internal chain, the FLESO) use the nominal model.
        self.model_parameters = ConfigParameters(
            self, MODEL_PREFIX, SMMParameters(), on_change=self._on_model
        )
        self.output_limits = ConfigParameters(
            self,
            OUTPUT_PREFIX,
            OutputLimitConfig(),
            on_change=self._on_output_limits,
        )
        self.limiter = OutputLimiter(self.output_limits.config)
        """Torque and rate limits after the law (shared with the internal chain: one clamp count)."""
        self.internal_chain = self.placement.config.chain == "internal"
        self.plausibility: PlausibilityCheck | None = None
        """Range and step check of ``joint_states`` (internal chain only; else ``td_node`` checks)."""
        if self.internal_chain:
            self.measurement_limits = ConfigParameters(
                self,
                MEASUREMENT_PREFIX,
                MeasurementLimits(),
                on_change=lambda limits: self._plausibility().reconfigure(limits),
            )
            self.plausibility = PlausibilityCheck(self.measurement_limits.config)
        self.chain: ControlChain | None = None
        """The TD -> FLESO -> law chain this node runs with ``chain = internal`` (None otherwise)."""
        if self.internal_chain:
            self.td_parameters = ConfigParameters(
                self,
                TD_PREFIX,
                TrackingDifferentiatorConfig(),
                check=lambda config: check_filter_factor(config, self.control_period),
                on_change=self._on_td,
            )
            self.fleso_parameters = ConfigParameters(
                self, FLESO_PREFIX, FLESOConfig(), on_change=self._on_fleso
            )
        self._last_command: FloatArray = np.zeros(2)
        self._reference: Sequence[Sequence[float]] = ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
        self._algorithm = self.selection.config.algorithm
        self.controller = self._build(self._algorithm)
        self.sync: ExactTimeSynchronizer[Any] = ExactTimeSynchronizer(self._inputs(self._algorithm))
        self._torque_publisher = self.create_publisher(
            Float64MultiArray, topics.TORQUE_COMMAND, qos_for_topic(topics.TORQUE_COMMAND)
        )
        self._internals_publisher = self.create_publisher(
            Float64MultiArray, topics.CONTROLLER_INTERNALS, qos_for_topic(topics.CONTROLLER_INTERNALS)
        )
        if self.internal_reference:
            self._reference_publisher = self.create_publisher(
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
            if not self.SUBSCRIBES_MEASUREMENT:
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

    def _on_output_limits(self, config: OutputLimitConfig) -> None:
        self.limiter.reconfigure(config)

    def _plausibility(self) -> PlausibilityCheck:
        assert self.plausibility is not None  # declared with the internal chain only
        return self.plausibility

    @property
    def algorithm(self) -> str:
        """Name of the running law."""
        return self._algorithm

    # ------------------------------------------------------------------------------ laws and switching

    def _build(self, name: str) -> JointController:
        """Build law ``name`` with its current gains; with the internal chain, a fresh chain around it."""
        built: JointController = _LAWS[name].build(
            self.law_parameters[name].config, self.model_parameters.config
        )
        if self.internal_chain:
            fleso = (
                FLESO(self.fleso_parameters.config, self.model_parameters.config)
                if _LAWS[name].uses_disturbance_estimate
                else None
            )
            self.chain = ControlChain(
                TrackingDifferentiator(self.td_parameters.config), fleso, built, self.limiter
            )
            self._last_command = np.zeros(2)
        return built

    @property
    def internal_reference(self) -> bool:
        """True with ``reference_source = internal``: this node samples the reference, nothing feeds it."""
        return self.reference is not None

    def _inputs(self, name: str) -> tuple[str, ...]:
        reference = () if self.internal_reference else (topics.REFERENCE,)
        if self.internal_chain:
            return (topics.JOINT_STATES, *reference)
        required = (topics.JOINT_STATES_FILTERED, *reference)
        return (*required, topics.DISTURBANCE_ESTIMATE) if _LAWS[name].uses_disturbance_estimate else required

    def _check_selection(self, candidate: ControllerSelection) -> None:
        if self._last_input_time is None or candidate.algorithm == self._algorithm:
            return
        quiet = time.monotonic() - self._last_input_time
        if quiet < candidate.switch_idle_time:
            raise ValueError(
                f"algorithm cannot change from {self._algorithm!r} to {candidate.algorithm!r} while the loop "
                f"is active: last input {quiet:.3f} s ago, switch_idle_time = {candidate.switch_idle_time} s "
                "(no law can take over bumplessly; stop the plant first)"
            )

    def _on_selection(self, selection: ControllerSelection) -> None:
        if selection.algorithm != self._algorithm:
            self._algorithm = selection.algorithm
            self.controller = self._build(self._algorithm)
            self.sync.set_inputs(self._inputs(self._algorithm))

    def _on_gains(self, name: str) -> Callable[[Any], None]:
        def reconfigure_if_running(_config: Any) -> None:
            # In place, so that the PID keeps its integrator (a rebuild would be a torque step under load).
            # A law that is not running takes its current gains when a switch builds it.
            if name == self._algorithm:
                _LAWS[name].reconfigure(
                    self.controller, self.law_parameters[name].config, self.model_parameters.config
                )

        return reconfigure_if_running

    def _on_model(self, _model: SMMParameters) -> None:
        self._on_gains("fpdeso")(_model)
        self._on_fleso(None)

    def _on_td(self, config: TrackingDifferentiatorConfig) -> None:
        if self.chain is not None:
            self.chain.td.reconfigure(config)

    def _on_fleso(self, _config: FLESOConfig | None) -> None:
        if self.chain is not None and self.chain.fleso is not None:
            self.chain.fleso.reconfigure(self.fleso_parameters.config, params=self.model_parameters.config)

    # --------------------------------------------------------------------------------------- inputs

    def _on_measurement(self, msg: JointState) -> None:
        self._on_input(topics.JOINT_STATES, msg, joint_state_to_sample)

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
        self._last_input_time = time.monotonic()
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
        if self.plausibility is not None and topic == topics.JOINT_STATES:
            position = (float(item.position[0]), float(item.position[1]))
            reason = self.plausibility.admit(position, item.stamp_ns, self.period_ns)
            if reason is not None:
                self.reject_implausible(topic, item.stamp_ns, reason)
                return
        matched = self.sync.add(topic, item.stamp_ns, item)
        self.counters.dropped_unmatched = self.sync.dropped
        if matched is not None:
            stamp_ns = matched.stamp_ns
            self.answer(stamp_ns, lambda: self._step(matched), lambda: self._diagnostics(stamp_ns))

    # ----------------------------------------------------------------------------------------- step

    def _reference_rows(self, matched: Matched[Any]) -> Sequence[Sequence[float]]:
        """The reference of the matched stamp, 3x2 floats: the input's, or sampled (``internal``)."""
        if self.reference is None:
            rows: list[list[float]] = matched.items[topics.REFERENCE].values.tolist()
            return rows
        return self.reference.generator.rows(self.reference_clock.time_s(matched.stamp_ns))

    def _step(self, matched: Matched[Any]) -> list[Output]:
        reference = self._reference_rows(matched)
        self._reference = reference
        if self.chain is not None:
            measurement = matched.items[topics.JOINT_STATES]
            applied = measurement.effort if measurement.effort is not None else self._last_command
            # The conversions validated shapes and finiteness, so the chain's float path skips the checks
            # of ControlChain.step (same arithmetic, same result).
            torque = self.chain.step_floats(
                (float(measurement.position[0]), float(measurement.position[1])),
                (float(applied[0]), float(applied[1])),
                reference,
                self.control_period,
            )
            output = self.torque_output(torque, matched.stamp_ns)  # raises for a non-finite torque
            self._last_command = np.array(torque)
            return [output]
        filtered = matched.items[topics.JOINT_STATES_FILTERED]
        estimate = matched.items.get(topics.DISTURBANCE_ESTIMATE)
        xi: FloatArray = np.zeros(2) if estimate is None else estimate.values[0]
        observer = estimate is not None and self.controller.velocity_source == "observer"
        velocity = estimate.values[1] if estimate is not None and observer else filtered.velocity
        # The conversions validated shapes and finiteness: step 4 of the chain, on floats.
        limited = limited_torque(
            self.controller,
            self.limiter,
            reference,
            (float(filtered.position[0]), float(filtered.position[1])),
            (float(velocity[0]), float(velocity[1])),
            disturbance=(float(xi[0]), float(xi[1])),
            dt=self.control_period,
        )
        return [self.torque_output(limited, matched.stamp_ns)]

    def torque_output(self, torque: tuple[float, float], stamp_ns: int) -> Output:
        """The ``torque_command`` output of a step (N m, shape (2,)).

        Raises:
            InterfaceError: The torque is not finite (the step then gives no output).
        """
        return (self._torque_publisher, torque_to_msg(np.array(torque), stamp_ns))

    def _diagnostics(self, stamp_ns: int) -> list[Output]:
        internals = (
            self.chain.internals
            if self.chain is not None
            else {
                **stage_internals("controller", self.controller.internals),
                **stage_internals("limiter", self.limiter.internals),
            }
        )
        rows = {**internals, **self.counter_rows()}
        outputs = [(self._internals_publisher, internals_to_msg(rows, stamp_ns))]
        if self.internal_reference:
            outputs.append((self._reference_publisher, reference_to_msg(np.array(self._reference), stamp_ns)))
        return outputs

    def on_time_jump(self, *, backward: bool) -> None:
        """Forget the old timeline's pending stamps; a new run (backward jump) starts from fresh state."""
        self.sync.clear()
        if backward:
            self.controller.reset()
            if self.chain is not None:
                self.chain.reset()
            self.limiter.reset()
            if self.plausibility is not None:
                self.plausibility.reset()
            self.reference_clock = ReferenceClock(self.get_logger().info)  # type: ignore[no-untyped-call]
            self._last_command = np.zeros(2)

    def health_counts(self) -> dict[str, int]:
        """The base counts plus ``clamps`` (steps whose torque the output limits changed)."""
        return {**super().health_counts(), "clamps": self.limiter.clamps}

    def health_warnings(self) -> tuple[str, ...]:
        """A clamp within the period makes the status WARN."""
        return (*super().health_warnings(), "clamps")


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``controller_node``: exit status 0 after Ctrl-C/SIGTERM, 2 for invalid parameters."""
    return node_main(lambda context: ControllerNode(context=context), args)


if __name__ == "__main__":
    sys.exit(main())
