"""Lifecycle nodes that survive a mistyped transition request."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.lifecycle import LifecycleNode

__all__ = ["refuse_invalid_transitions"]


def refuse_invalid_transitions(node: LifecycleNode) -> None:
    """``node``'s ``~/change_state`` answers a transition its current state lacks with ``success: false``.

    rclpy raises ``RCLError`` for an unknown transition id out of the service callback, which ends the
    executor's spin and the process: one mistyped ``ros2 lifecycle set`` would stop the control loop.
    """
    service = node._service_change_state
    service.callback = _refusing(service.callback, node.get_logger())  # type: ignore[no-untyped-call]


def _refusing(callback: Callable[[Any, Any], Any], log: Any) -> Callable[[Any, Any], Any]:
    def change_state(request: Any, response: Any) -> Any:
        try:
            return callback(request, response)
        except rclpy_implementation.RCLError as error:
            transition = request.transition
            log.warning(f"change_state: transition {transition.id} {transition.label!r} refused: {error}")
            response.success = False
            return response

    return change_state
