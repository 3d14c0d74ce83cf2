"""``/diagnostics`` for every SMM node: one ``DiagnosticStatus`` once a period and on every level change."""

from __future__ import annotations

from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from smm_msgs_py.qos import diagnostic_qos
from smm_msgs_py.topics import DIAGNOSTICS

from smm_node_runtime.health import CountWindows, Health, Level, level_for, worst

__all__ = [
    "DEFAULT_PERIOD_S",
    "HARDWARE_ID",
    "CountWindows",
    "DiagnosticsPublisher",
    "Health",
    "Level",
    "level_for",
    "worst",
]

DEFAULT_PERIOD_S = 1.0
"""Period of the status messages (s), wall clock (steady), also when the node runs on sim time."""

HARDWARE_ID = "smm"
"""``hardware_id`` of every status of the stack."""


class DiagnosticsPublisher:
    """Publishes ``collect()`` on ``/diagnostics`` every ``period_s`` and when :meth:`check` sees a new level.

    Args:
        node: The node whose health this is (the status is named by its fully qualified name).
        collect: Returns the node's current :class:`Health`; called from the node's executor.
        period_s: Period of the regular status (s), > 0.
        on_period: Called at the end of every period, before its status is collected (e.g. to roll the
            counters the thresholds judge per period).
    """

    def __init__(
        self,
        node: Node,
        collect: Callable[[], Health],
        period_s: float = DEFAULT_PERIOD_S,
        on_period: Callable[[], None] | None = None,
    ) -> None:
        if not period_s > 0.0:
            raise ValueError(f"diagnostics period must be > 0 s, got {period_s!r}")
        self._node = node
        self._collect = collect
        self._publisher = node.create_publisher(DiagnosticArray, DIAGNOSTICS, diagnostic_qos())
        self._on_period = on_period
        self._timer = node.create_timer(
            period_s, self._on_timer, clock=Clock(clock_type=ClockType.STEADY_TIME)
        )
        self._level: Level | None = None
        self.published = 0
        """Number of status messages sent."""

    @property
    def level(self) -> Level | None:
        """Level of the last status sent (None before the first)."""
        return self._level

    def publish(self) -> Health:
        """Collect and send the status now; return it."""
        health = self._collect()
        status = DiagnosticStatus(
            level=bytes([int(health.level)]),
            name=self._node.get_fully_qualified_name(),
            message=health.message,
            hardware_id=HARDWARE_ID,
            values=[KeyValue(key=key, value=str(value)) for key, value in health.values.items()],
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = self._node.get_clock().now().to_msg()
        self._publisher.publish(array)
        self._level = health.level
        self.published += 1
        return health

    def _on_timer(self) -> None:
        if self._on_period is not None:
            self._on_period()
        self.publish()

    def check(self) -> None:
        """Send the status now if its level differs from the last one sent (call after an event)."""
        if self._collect().level != self._level:
            self.publish()

    def destroy(self) -> None:
        """Stop the timer and destroy the publisher."""
        self._node.destroy_timer(self._timer)
        self._node.destroy_publisher(self._publisher)
