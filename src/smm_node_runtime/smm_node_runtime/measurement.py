"""What every SMM node shares: the Jazzy-safe main, the executor choice, and the stamp/bad-input policy.

* :func:`run_node` / :func:`run_nodes`: ``rclpy.init`` on a context of their own, spin one or several nodes
  in one executor, and on Ctrl-C, SIGTERM-driven shutdown or ``ExternalShutdownException`` destroy the nodes
  and ``try_shutdown`` the context, so a node exits 0 without a traceback. They first set
  ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` when the variable is unset (the stack never discovers over the
  network unless the caller asks for it).
* :func:`make_executor`: ``rclpy.experimental.EventsExecutor`` when this rclpy has it (about 15 times more
  message round trips per second than ``SingleThreadedExecutor`` here: 5500/s against 370/s, two nodes
  ping-ponging a JointState in one process), else ``SingleThreadedExecutor``. Both run callbacks one at a
  time, which the nodes rely on.
  The EventsExecutor of rclpy 7.1.x (Jazzy) never returns from a wait without a timeout (``spin()``,
  ``spin_once()``, ``spin_until_future_complete(f)``) and holds the GIL there: timers do not fire, other
  Python threads and Ctrl-C starve. Timed waits work, so the executor returned is wrapped to bound every
  wait (:data:`SPIN_POLL_S`); callers may use it like any executor.
* :func:`spin_until_shutdown`: ``spin_once`` in a loop until the context shuts down or a stop is requested.
* :class:`MeasurementDrivenNode`: base class of the nodes that answer measurements. Every output carries
  the stamp of the measurement it answers, and the policy for stamps is the same everywhere:

  - a stamp newer than the last answered one is new: the node processes it (once all inputs for it are in);
  - a stamp equal to the last answered one is a re-transmission (the lockstep simulator re-sends the current
    measurement until it sees an answer): the node re-publishes its last answer, unchanged, without
    stepping its algorithm again;
  - an older stamp is stale: dropped, counted, warned about (throttled);
  - an input that breaks the interface contract (NaN/Inf, wrong length, unknown joint, bad layout or stamp:
    any :class:`~smm_msgs_py.errors.InterfaceError`) is dropped, counted, warned about (throttled per input
    topic), and never produces an output.

  The counters go out with the node's internals (:data:`COUNTER_ROWS`, each row holding the count in both
  columns so that it fits the per-joint labelled-array layout).
"""

from __future__ import annotations

import enum
import os
import signal
import sys
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt
import rclpy
from rclpy.context import Context
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions

__all__ = [
    "COUNTER_ROWS",
    "DEFAULT_CONTROL_PERIOD",
    "DISCOVERY_RANGE_VARIABLE",
    "EXIT_INVALID_PARAMETER",
    "EXIT_OK",
    "SPIN_POLL_S",
    "WARN_THROTTLE_S",
    "Admission",
    "ControlPeriodConfig",
    "InputCounters",
    "MeasurementDrivenNode",
    "NodeFactory",
    "Output",
    "ParameterOverrides",
    "StampGate",
    "as_parameter_list",
    "ensure_localhost_discovery",
    "make_executor",
    "node_main",
    "run_node",
    "run_nodes",
    "spin_until_shutdown",
]

DISCOVERY_RANGE_VARIABLE: Final[str] = "ROS_AUTOMATIC_DISCOVERY_RANGE"
EXIT_OK: Final[int] = 0
"""Exit status of a node process stopped by a signal or a shutdown."""

EXIT_INVALID_PARAMETER: Final[int] = 2
"""Exit status of a node process whose initial parameters were refused (as smm_sim_node)."""

SPIN_POLL_S: Final[float] = 0.1
"""Longest wait of one ``spin_once`` (s): how late a shutdown can be noticed when nothing arrives."""

WARN_THROTTLE_S: Final[float] = 1.0
"""At most one warning per input topic and per this many seconds (s); the counters count every drop."""

Output = tuple[Publisher, Any]
"""A message ready to go: ``(publisher, message)``."""

ParameterOverrides = Sequence[Parameter] | Mapping[str, Any]
"""Parameter overrides for a node: ``rclpy.parameter.Parameter`` objects or ``{name: value}``."""

NodeFactory = Callable[[Context], Node]
"""Builds a node in the given (initialised) context, e.g. ``lambda context: TdNode(context=context)``."""


# ------------------------------------------------------------------------------------------ process


def ensure_localhost_discovery() -> None:
    """Set ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless the environment already chose a range.

    Must run before ``rclpy.init``: the middleware reads the variable when the context starts.
    """
    os.environ.setdefault(DISCOVERY_RANGE_VARIABLE, "LOCALHOST")


class _BoundedWaitExecutor:
    """Wrap rclpy 7.1's EventsExecutor so that no call waits without a timeout.

    Any wait without a timeout (``spin()``, ``spin_once()``, ``spin_until_future_complete(f)``) of that
    executor blocks for ever while holding the GIL: timers never fire, other Python threads and signal
    handlers starve. Timed waits work. This wrapper turns every untimed wait into a loop of waits of at most
    :data:`SPIN_POLL_S`, and delegates everything else.
    """

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def spin(self) -> None:
        """Execute callbacks until the context shuts down."""
        while self._inner.context.ok():
            self._inner.spin_once(timeout_sec=SPIN_POLL_S)

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Execute one callback, waiting at most ``timeout_sec`` (None or negative: :data:`SPIN_POLL_S`)."""
        bounded = SPIN_POLL_S if timeout_sec is None or timeout_sec < 0.0 else timeout_sec
        self._inner.spin_once(timeout_sec=bounded)

    def spin_until_future_complete(self, future: Any, timeout_sec: float | None = None) -> None:
        """Execute callbacks until ``future`` is done, the context shuts down or ``timeout_sec`` passes."""
        if timeout_sec is not None and timeout_sec >= 0.0:
            self._inner.spin_until_future_complete(future, timeout_sec=timeout_sec)
            return
        while self._inner.context.ok() and not future.done():
            self._inner.spin_until_future_complete(future, timeout_sec=SPIN_POLL_S)

    def spin_once_until_future_complete(self, future: Any, timeout_sec: float | None = None) -> None:
        """Execute one callback or until ``future`` is done (untimed waits bounded as in ``spin_once``)."""
        bounded = SPIN_POLL_S if timeout_sec is None or timeout_sec < 0.0 else timeout_sec
        self._inner.spin_once_until_future_complete(future, timeout_sec=bounded)


def make_executor(context: Context | None = None) -> Executor:
    """Return the executor the stack spins its nodes with.

    Args:
        context: The (initialised) context the executor serves; None for rclpy's default context.

    Returns:
        ``rclpy.experimental.EventsExecutor`` when importable, wrapped so that no wait is untimed (see
        :class:`_BoundedWaitExecutor`: ``spin()``, ``spin_until_future_complete(f)`` and ``spin_once()``
        are safe to call), else a ``SingleThreadedExecutor``. Both execute one callback at a time.
        ``spin_once()`` without a timeout returns after at most :data:`SPIN_POLL_S` even if nothing ran.
    """
    try:
        from rclpy.experimental import EventsExecutor  # type: ignore[attr-defined]  # noqa: PLC0415
    except ImportError:
        return SingleThreadedExecutor(context=context)
    return typing.cast(Executor, _BoundedWaitExecutor(EventsExecutor(context=context)))


def spin_until_shutdown(
    executor: Executor, context: Context, stop_requested: Callable[[], bool] = lambda: False
) -> None:
    """Execute callbacks until ``context`` shuts down or ``stop_requested()`` holds.

    Never calls ``executor.spin()`` (see the module docstring); a stop is noticed within
    :data:`SPIN_POLL_S` when idle, or after the callback that is running.

    Args:
        executor: The executor, with its nodes added.
        context: The context whose shutdown ends the loop.
        stop_requested: Polled between callbacks; True ends the loop (set by a signal handler).

    Raises:
        KeyboardInterrupt, ExternalShutdownException: as ``spin_once`` raises them.
    """
    while context.ok() and not stop_requested():
        executor.spin_once(timeout_sec=SPIN_POLL_S)


class _StopSignals:
    """SIGINT/SIGTERM handlers that only raise a flag, so the spin loop ends between two callbacks.

    rclpy's own handlers are not used (``SignalHandlerOptions.NO``): its SIGINT handler shuts the context
    down under a running callback and then raises ``KeyboardInterrupt`` inside it, and it does not handle
    SIGTERM at all, so the default action killed the process before the nodes were destroyed. Handlers can
    only be set from the main thread; elsewhere the process's handlers are left alone.
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.requested = False
        self._previous: dict[int, Any] = {}

    def _handle(self, _signum: int, _frame: object) -> None:
        self.requested = True

    def install(self) -> None:
        try:
            for signum in self.SIGNALS:
                self._previous[signum] = signal.signal(signum, self._handle)
        except ValueError:  # not the main thread
            self.restore()

    def restore(self) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()


def run_nodes(node_factories: Sequence[NodeFactory], args: Sequence[str] | None = None) -> None:
    """Initialise ROS, build the nodes, spin them in one executor until shutdown, then clean up.

    SIGINT (Ctrl-C) and SIGTERM end the spin between two callbacks; then the executor is shut down, the
    nodes destroyed (in reverse order) and the context shut down, and the function returns normally.
    ``ExternalShutdownException`` (context shut down elsewhere) ends it the same way. Any other exception,
    e.g. a node refusing its initial parameters, propagates after the same clean-up.

    Args:
        node_factories: One factory per node; all nodes share one context and one executor (composition).
        args: Command-line arguments (``--ros-args ...`` is consumed by ROS); None for ``sys.argv``.
    """
    ensure_localhost_discovery()
    stop = _StopSignals()
    stop.install()
    context = Context()
    nodes: list[Node] = []
    executor: Executor | None = None
    try:
        rclpy.init(
            args=None if args is None else list(args),
            context=context,
            signal_handler_options=SignalHandlerOptions.NO,
        )
        for factory in node_factories:
            nodes.append(factory(context))
        executor = make_executor(context)
        for node in nodes:
            executor.add_node(node)
        spin_until_shutdown(executor, context, lambda: stop.requested)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if executor is not None:
            executor.shutdown()
        for node in reversed(nodes):
            node.destroy_node()  # type: ignore[no-untyped-call]
        context.try_shutdown()
        stop.restore()


def run_node(node_factory: NodeFactory, args: Sequence[str] | None = None) -> None:
    """Run one node: :func:`run_nodes` with a single factory."""
    run_nodes([node_factory], args)


def node_main(node_factory: NodeFactory, args: Sequence[str] | None = None) -> int:
    """Body of a node's console script: :func:`run_node`, with invalid parameters as exit status 2.

    A node that refuses its initial parameters (a config ``ValueError``, or rclpy's
    ``ParameterException``, e.g. an integer array for a double-array parameter) is reported on stderr as
    ``<node>: invalid parameter: <reason>`` in one line, without a traceback.

    Returns:
        :data:`EXIT_OK` after a shutdown, :data:`EXIT_INVALID_PARAMETER` when the node refused its
        parameters.
    """
    try:
        run_node(node_factory, args)
    except (ValueError, ParameterException) as error:
        print(f"invalid parameter: {error}", file=sys.stderr)
        return EXIT_INVALID_PARAMETER
    return EXIT_OK


def as_parameter_list(overrides: ParameterOverrides | None) -> list[Parameter] | None:
    """Normalise parameter overrides to what ``rclpy.node.Node`` takes.

    Args:
        overrides: ``Parameter`` objects, or ``{name: value}`` (the value's Python type gives the ROS type,
            as a parameter file does: ``[1, 2]`` is an integer array, ``[1.0, 2.0]`` a double array).

    Returns:
        A list of ``Parameter``, or None for None.
    """
    if overrides is None:
        return None
    if isinstance(overrides, Mapping):
        return [
            Parameter(name, value=_parameter_value(value))  # type: ignore[no-untyped-call]
            for name, value in overrides.items()
        ]
    return list(overrides)


def _parameter_value(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


# ------------------------------------------------------------------------------------- parameters


DEFAULT_CONTROL_PERIOD: Final[float] = 1e-3
"""Default control period (s): 1 kHz, the paper's."""


@dataclass(frozen=True)
class ControlPeriodConfig:
    """The step size a node integrates its algorithm with (declared read-only: fixed at start-up).

    Attributes:
        control_period: Control period dt (s), > 0 and finite; must equal the plant's period (the
            simulator's ``control_period``), because nodes step once per measurement with this dt.
    """

    control_period: float = DEFAULT_CONTROL_PERIOD

    def __post_init__(self) -> None:
        value = self.control_period
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 < value < float("inf"):
            raise ValueError(f"control_period must be a finite number of seconds > 0, got {value!r}")


# --------------------------------------------------------------------------------- stamps and drops


class Admission(enum.Enum):
    """What to do with an incoming stamp, relative to the last answered stamp."""

    NEW = "new"
    DUPLICATE = "duplicate"
    STALE = "stale"


class StampGate:
    """Remember the last answered stamp and classify incoming ones (pure, no ROS)."""

    def __init__(self) -> None:
        self._last_stamp_ns: int | None = None

    @property
    def last_stamp_ns(self) -> int | None:
        """Stamp of the last answered measurement (ns), None before the first."""
        return self._last_stamp_ns

    def classify(self, stamp_ns: int) -> Admission:
        """Classify ``stamp_ns`` (ns): NEW if newer than the last answered, DUPLICATE if equal, else STALE."""
        last = self._last_stamp_ns
        if last is None or stamp_ns > last:
            return Admission.NEW
        return Admission.DUPLICATE if stamp_ns == last else Admission.STALE

    def mark_answered(self, stamp_ns: int) -> None:
        """Record ``stamp_ns`` (ns) as answered.

        Raises:
            ValueError: ``stamp_ns`` is not newer than the last answered stamp.
        """
        if self._last_stamp_ns is not None and stamp_ns <= self._last_stamp_ns:
            raise ValueError(
                f"stamp {stamp_ns} ns is not newer than the last answered {self._last_stamp_ns} ns"
            )
        self._last_stamp_ns = stamp_ns

    def reset(self) -> None:
        """Forget the last answered stamp (every stamp is NEW again)."""
        self._last_stamp_ns = None


COUNTER_ROWS: Final[tuple[str, ...]] = (
    "dropped_invalid",
    "dropped_stale",
    "dropped_unmatched",
    "duplicates_answered",
    "invalid_outputs",
)
"""Internals rows of the node counters (same count in both columns)."""


@dataclass
class InputCounters:
    """Counts of what a node did not process normally, since start.

    Attributes:
        dropped_invalid: Inputs breaking the interface contract (NaN/Inf, length, joint, layout, stamp).
        dropped_stale: Inputs older than the last answered stamp.
        dropped_unmatched: Stamps dropped by the synchroniser before all inputs for them arrived.
        duplicates_answered: Re-transmitted inputs answered by re-publishing the last answer.
        invalid_outputs: Steps whose output broke the contract (e.g. non-finite) and was not published.
    """

    dropped_invalid: int = 0
    dropped_stale: int = 0
    dropped_unmatched: int = 0
    duplicates_answered: int = 0
    invalid_outputs: int = 0

    def rows(self) -> dict[str, npt.NDArray[np.float64]]:
        """Return ``{row name: [count, count]}`` in :data:`COUNTER_ROWS` order, for an internals message."""
        return {name: np.full(2, float(getattr(self, name))) for name in COUNTER_ROWS}


class MeasurementDrivenNode(Node):
    """Base class of a node that answers stamped measurements (see the module docstring for the policy).

    Subclasses: parse each input with the ``smm_msgs_py`` conversions inside ``try: ... except
    InterfaceError as error: self.reject(topic, error)``; call :meth:`admit` with the stamp and return
    unless it is True; when the step for a stamp is done, build the output messages and hand them to
    :meth:`answer` (a conversion error there is counted as an invalid output and nothing is published).

    Args:
        node_name: Node name.
        context: rclpy context (None: the default one); lets a launcher compose nodes in one process and
            tests use a private context.
        parameter_overrides: Values overriding the declared defaults and parameter files: ``Parameter``
            objects or ``{name: value}`` (see :func:`as_parameter_list`).
        namespace: Node namespace (None: from the command line, else the root).
        cli_args: Node-specific command-line arguments (as ``rclpy.node.Node``).
    """

    def __init__(
        self,
        node_name: str,
        *,
        context: Context | None = None,
        parameter_overrides: ParameterOverrides | None = None,
        namespace: str | None = None,
        cli_args: Sequence[str] | None = None,
    ) -> None:
        super().__init__(
            node_name,
            context=context,
            parameter_overrides=as_parameter_list(parameter_overrides),
            namespace=namespace,
            cli_args=None if cli_args is None else list(cli_args),
        )
        self.counters = InputCounters()
        self._gate = StampGate()
        self._last_answer: tuple[Output, ...] = ()
        # Publishers the diagnostics went to, learnt from the first build: while none of them has a
        # subscriber, diagnostics are neither built nor published (lazy publishing, as image_transport
        # does), which is indistinguishable from publishing to nobody and halves the work per step.
        self._diagnostic_publishers: tuple[Publisher, ...] | None = None
        self._topic_loggers: dict[str, RcutilsLogger] = {}

    @property
    def last_answered_stamp_ns(self) -> int | None:
        """Stamp (ns) of the last measurement this node answered, None before the first."""
        return self._gate.last_stamp_ns

    def warn_throttled(self, topic: str, message: str) -> None:
        """Log a warning, at most once per :data:`WARN_THROTTLE_S` per ``topic`` (throttled per topic)."""
        logger = self._topic_loggers.get(topic)
        if logger is None:
            child_name = topic.strip("~/").replace("/", ".")
            logger = self.get_logger().get_child(child_name)  # type: ignore[no-untyped-call]
            self._topic_loggers[topic] = logger
        logger.warning(message, throttle_duration_sec=WARN_THROTTLE_S)

    def reject(self, topic: str, error: Exception) -> None:
        """Drop an input that broke the interface contract: count it and warn (throttled)."""
        self.counters.dropped_invalid += 1
        self.warn_throttled(
            topic,
            f"dropped input on '{topic}' ({type(error).__name__}: {error}); "
            f"{self.counters.dropped_invalid} invalid inputs so far",
        )

    def admit(self, topic: str, stamp_ns: int) -> bool:
        """Apply the stamp policy to an input stamped ``stamp_ns`` (ns) on ``topic``.

        Returns:
            True when the stamp is new (the caller processes the input). False for a duplicate (the last
            answer has been re-published) or a stale stamp (counted and warned about).
        """
        admission = self._gate.classify(stamp_ns)
        if admission is Admission.NEW:
            return True
        if admission is Admission.DUPLICATE:
            self.counters.duplicates_answered += 1
            for publisher, message in self._last_answer:
                publisher.publish(message)
            return False
        self.counters.dropped_stale += 1
        self.warn_throttled(
            topic,
            f"dropped stale input on '{topic}': stamp {stamp_ns} ns is older than the last answered "
            f"{self._gate.last_stamp_ns} ns; {self.counters.dropped_stale} stale inputs so far",
        )
        return False

    def answer(
        self,
        stamp_ns: int,
        build_outputs: Callable[[], Sequence[Output]],
        build_diagnostics: Callable[[], Sequence[Output]] | None = None,
    ) -> bool:
        """Publish what answers ``stamp_ns`` (ns): the control-chain outputs, then the diagnostics.

        The stamp is marked answered even when building the outputs fails (the algorithm has stepped), so a
        re-transmission is not stepped again; it then gets no answer. Only the control-chain outputs are
        re-published for a re-transmission: a recorder never sees a diagnostic twice.

        Args:
            stamp_ns: Stamp of the answered measurement (ns), newer than the last answered one.
            build_outputs: Steps the algorithm and builds the control-chain ``(publisher, message)``
                pairs, all or nothing; a ``ValueError`` (an ``InterfaceError`` from the conversions for a
                non-finite or mis-shaped output, or an algorithm's own input check) is counted in
                ``invalid_outputs``, warned about, and nothing is published.
            build_diagnostics: Builds the diagnostic pairs (internals); published after the outputs, and
                only while one of their topics has a subscriber (a recorder, a plot): unobserved
                diagnostics cost nothing. A conversion error there is counted and warned about the same
                way.

        Returns:
            True when the control-chain outputs were published.
        """
        self._gate.mark_answered(stamp_ns)
        outputs = self._built(stamp_ns, build_outputs)
        self._last_answer = () if outputs is None else outputs
        if outputs is None:
            return False
        for publisher, message in outputs:
            publisher.publish(message)
        if build_diagnostics is not None and self._diagnostics_observed():
            diagnostics = self._built(stamp_ns, build_diagnostics)
            if diagnostics is not None and self._diagnostic_publishers is None:
                self._diagnostic_publishers = tuple(publisher for publisher, _ in diagnostics)
            for publisher, message in diagnostics or ():
                publisher.publish(message)
        return True

    def _diagnostics_observed(self) -> bool:
        """True when a diagnostics topic has a subscriber (or before the first diagnostics were built)."""
        if self._diagnostic_publishers is None:
            return True
        return any(publisher.get_subscription_count() > 0 for publisher in self._diagnostic_publishers)

    def _built(self, stamp_ns: int, build: Callable[[], Sequence[Output]]) -> tuple[Output, ...] | None:
        try:
            return tuple(build())
        except ValueError as error:  # InterfaceError from a conversion, or an algorithm's input check
            self.step_failed(stamp_ns, error)
            return None

    def step_failed(self, stamp_ns: int, error: Exception) -> None:
        """Count and warn about a step whose result cannot be published (nothing is published)."""
        self.counters.invalid_outputs += 1
        self.warn_throttled(
            "~/outputs",
            f"no output for stamp {stamp_ns} ns ({type(error).__name__}: {error}); "
            f"{self.counters.invalid_outputs} invalid outputs so far",
        )

    def counter_rows(self) -> Mapping[str, npt.NDArray[np.float64]]:
        """The node counters as internals rows (see :meth:`InputCounters.rows`)."""
        return self.counters.rows()
