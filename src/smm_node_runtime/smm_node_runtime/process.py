"""How an SMM node process runs: localhost discovery, the executor, signals, and the console-script main.

Why EventsExecutor and why every wait is bounded: ``docs/NODES.md``, "Process lifetime".
"""

from __future__ import annotations

import os
import signal
import sys
import typing
from collections.abc import Callable, Sequence
from typing import Any, Final

import rclpy
from rclpy.context import Context
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from smm_node_runtime.parameter_check import check_node_arguments
from smm_node_runtime.parameter_files import ParameterFileError

__all__ = [
    "DISCOVERY_RANGE_VARIABLE",
    "EXIT_INVALID_PARAMETER",
    "EXIT_OK",
    "SPIN_POLL_S",
    "NodeFactory",
    "ensure_localhost_discovery",
    "make_executor",
    "node_main",
    "refused",
    "run_node",
    "run_nodes",
    "spin_until_shutdown",
]

DISCOVERY_RANGE_VARIABLE: Final[str] = "ROS_AUTOMATIC_DISCOVERY_RANGE"
EXIT_OK: Final[int] = 0
"""Exit status of a node process stopped by a signal or a shutdown."""

EXIT_INVALID_PARAMETER: Final[int] = 2
"""Exit status of a node process whose initial parameters were refused."""

SPIN_POLL_S: Final[float] = 0.1
"""Longest wait of one ``spin_once`` (s): how late a shutdown can be noticed when nothing arrives."""

NodeFactory = Callable[[Context], Node]
"""Builds a node in the given (initialised) context, e.g. ``lambda context: TdNode(context=context)``."""


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


def run_nodes(
    node_factories: Sequence[NodeFactory], args: Sequence[str] | None = None, *, nodes: Sequence[str] = ()
) -> None:
    """Check the arguments, initialise ROS, build the nodes, spin them in one executor until shutdown.

    SIGINT (Ctrl-C) and SIGTERM end the spin between two callbacks; then the executor is shut down, the
    nodes destroyed (in reverse order) and the context shut down, and the function returns normally.
    ``ExternalShutdownException`` (context shut down elsewhere) ends it the same way. Any other exception,
    e.g. a node refusing its initial parameters, propagates after the same clean-up.

    Args:
        node_factories: One factory per node; all nodes share one context and one executor (composition).
        args: Command-line arguments (``--ros-args ...`` is consumed by ROS); None for ``sys.argv``.
        nodes: Names of the stack's nodes the factories build: their parameter files and ``-p`` overrides
            are checked first (:func:`smm_node_runtime.parameter_check.check_node_arguments`).

    Raises:
        ParameterFileError: A parameter file or override is missing, malformed or names an unknown
            parameter or node, or rcl refused the arguments; raised before any node exists.
    """
    if nodes:
        check_node_arguments(args, nodes)
    ensure_localhost_discovery()
    stop = _StopSignals()
    stop.install()
    context = Context()
    built: list[Node] = []
    executor: Executor | None = None
    try:
        try:
            rclpy.init(
                args=None if args is None else list(args),
                context=context,
                signal_handler_options=SignalHandlerOptions.NO,
            )
        except _rclpy.RCLError as error:  # what the check above does not foresee, in rcl's words
            raise ParameterFileError(
                f"ROS refused the command line: {' '.join(str(error).split())}"
            ) from None
        for factory in node_factories:
            built.append(factory(context))
        executor = make_executor(context)
        for node in built:
            executor.add_node(node)
        spin_until_shutdown(executor, context, lambda: stop.requested)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if executor is not None:
            executor.shutdown()
        for node in reversed(built):
            node.destroy_node()  # type: ignore[no-untyped-call]
        context.try_shutdown()
        stop.restore()


def run_node(node_factory: NodeFactory, args: Sequence[str] | None = None, *, node: str = "") -> None:
    """Run one node: :func:`run_nodes` with a single factory (``node``: its name in the stack)."""
    run_nodes([node_factory], args, nodes=(node,) if node else ())


def refused(
    run: Callable[[], int],
    process: str,
    invalid: tuple[type[Exception], ...] = (ValueError, ParameterException),
) -> int:
    """``run()``, with refused arguments or initial parameters as one line on stderr and exit status 2.

    A bad parameter file or ``-p`` (:class:`ParameterFileError`) and a node refusing its initial parameters
    (``invalid``: a config ``ValueError``, or rclpy's ``ParameterException``, e.g. an integer array for a
    double-array parameter) are reported as ``<process>: <reason>`` / ``<process>: invalid parameter:
    <reason>``, without a traceback.
    """
    try:
        return run()
    except ParameterFileError as error:
        print(f"{process}: {error}", file=sys.stderr)
    except invalid as error:
        print(f"{process}: invalid parameter: {error}", file=sys.stderr)
    return EXIT_INVALID_PARAMETER


def node_main(node_factory: NodeFactory, args: Sequence[str] | None = None, *, node: str = "") -> int:
    """Body of a node's console script: :func:`run_node` of the stack's node ``node``, refusals as exit 2.

    Returns:
        :data:`EXIT_OK` after a shutdown, :data:`EXIT_INVALID_PARAMETER` when the arguments or the node
        refused its parameters (:func:`refused`).
    """

    def run() -> int:
        run_node(node_factory, args, node=node)
        return EXIT_OK

    return refused(run, node or "node")
