"""``smm-launch --composed``: every node of the graph in this process, in one executor."""

from __future__ import annotations

import signal
import sys
from collections.abc import Sequence
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions

from smm_bringup.errors import GraphError
from smm_bringup.graph_nodes import NAMESPACE, PLANT_NODE_NAMES, NodeSpec, parameter_overrides
from smm_bringup.supervisor import (
    _POLL_S,
    EXIT_NODE_FAILED,
    EXIT_NOT_CONTROLLED,
    EXIT_OK,
    _say,
    _stop_signals,
    _StopRequest,
)
from smm_node_runtime import as_parameter_list, ensure_localhost_discovery, make_executor

__all__ = ["launch_composed"]


def launch_composed(specs: Sequence[NodeSpec]) -> int:
    """Run every node of the graph in this process, in one executor.

    Each node class gets the parameter values its spec sets (files, then overrides) as
    ``parameter_overrides``; the namespace is applied as a global remapping of the context.

    Returns:
        0 when the plant completed its run, 3 when it completed a real-time run that did not control (its
        ``run_verdict``), 128 + signal number after Ctrl-C / SIGTERM, 1 when a node failed (its exception
        is reported).
    """
    if any(not spec.node_class for spec in specs):
        names = [spec.name for spec in specs if not spec.node_class]
        raise GraphError(
            f"composed mode runs ROS nodes only; {names} must run as processes (drop --composed)"
        )
    ensure_localhost_discovery()
    context = Context()
    namespaces = {spec.namespace for spec in specs}
    if len(namespaces) != 1:
        raise GraphError(f"composed mode needs one namespace for all nodes, got {sorted(namespaces)}")
    # Signals are this function's to handle (one stop request, one exit code), not rclpy's.
    rclpy.init(
        args=["smm-launch", "--ros-args", "-r", f"__ns:=/{namespaces.pop() or NAMESPACE}"],
        context=context,
        signal_handler_options=SignalHandlerOptions.NO,
    )
    nodes: list[Any] = []
    executor = None
    request = _StopRequest()
    try:
        for spec in specs:
            overrides = as_parameter_list(parameter_overrides(spec))
            try:
                node = spec.load_class()(context=context, parameter_overrides=overrides)
            except ValueError as error:
                raise GraphError(f"{spec.name}: invalid parameter: {error}") from error
            if node.get_name() != spec.name:
                raise GraphError(
                    f"{spec.node_class} created node {node.get_name()!r}, the graph expects {spec.name!r}"
                )
            nodes.append(node)
            _say(f"created {spec.name} ({spec.node_class}) in this process")
        executor = make_executor(context)
        for node in nodes:
            executor.add_node(node)
        plant = next((n for n, s in zip(nodes, specs, strict=True) if s.name in PLANT_NODE_NAMES), None)
        done = getattr(plant, "done", None)
        with _stop_signals(request):
            while not request.event.is_set() and context.ok():
                if done is not None:
                    executor.spin_until_future_complete(done, timeout_sec=_POLL_S * 4)
                    if done.done():
                        if done.exception() is not None:
                            _say(f"the plant failed: {done.exception()}", sys.stderr)
                            return EXIT_NODE_FAILED
                        _say("the plant completed its run; stopping the graph")
                        judge = getattr(plant, "run_verdict", None)
                        reason = judge() if judge is not None else None
                        if reason is not None:
                            _say(f"run: did not control: {reason}", sys.stderr)
                            return EXIT_NOT_CONTROLLED
                        return EXIT_OK
                else:
                    executor.spin_once(timeout_sec=_POLL_S * 4)
        signum = request.signal_number or signal.SIGINT
        _say(f"received {signal.Signals(signum).name}; stopping the graph")
        return 128 + signum
    except (KeyboardInterrupt, ExternalShutdownException):
        return 128 + signal.SIGINT
    except GraphError:
        raise
    except Exception as error:  # a node's callback raised: report which, stop everything
        _say(f"a node failed: {type(error).__name__}: {error}", sys.stderr)
        return EXIT_NODE_FAILED
    finally:
        if executor is not None:
            executor.shutdown()
        for node in reversed(nodes):
            node.destroy_node()
        context.try_shutdown()
