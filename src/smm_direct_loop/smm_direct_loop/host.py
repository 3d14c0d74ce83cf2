"""``direct_loop``: ``hw_bridge_node`` and ``controller_node`` in one process, the chain in the bridge's tick.

The process composes the two nodes and the bridge's loop (:class:`~smm_hw_bridge.loop.BridgeLoop`): the
loop steps :meth:`ControllerCore.measurement` on each feedback and writes its command in the same call; the
controller's parameter changes wait in the loop's :class:`~smm_hw_bridge.loop.ChangeBuffer` for a tick
boundary. Why and when: docs/LAUNCH.md, "The direct loop"; the loop: docs/DESIGN.md.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from typing import Any

from rclpy.context import Context
from smm_controller.controller_node import ControllerNode
from smm_controller.core import Refusal, StepResult
from smm_hw_bridge.bridge_node import HwBridgeNode
from smm_hw_bridge.bridge_run import judged_exit
from smm_hw_bridge.loop import ChangeBuffer

from smm_msgs_py import topics
from smm_node_runtime import refused, run_nodes

__all__ = ["HostedController", "compose", "main"]

PROCESS_NAME = "direct_loop"


class HostedController:
    """``controller_node``'s core as the bridge loop's answerer (:class:`~smm_hw_bridge.loop.Answerer`).

    Args:
        controller: A ``controller_node`` built with the loop's change buffer (it takes no ``joint_states``).

    Raises:
        ValueError: ``chain`` or ``reference_source`` is not ``internal``.
    """

    def __init__(self, controller: ControllerNode) -> None:
        if not controller.internal_chain or not controller.internal_reference:
            raise ValueError(
                "the direct loop steps the whole chain itself: chain and reference_source must be 'internal'"
            )
        self.controller = controller
        self._period = controller.control_period
        self._pending: StepResult | None = None

    def answer(
        self, stamp_ns: int, position: tuple[float, float], effort: tuple[float, float]
    ) -> tuple[float, float] | str | None:
        """Steps the core on one measurement (rad, N m applied): the torque, why the chain failed, or None."""
        controller = self.controller
        started = time.perf_counter()
        controller.last_input_s = time.monotonic()
        result = controller.core.measurement(
            topics.JOINT_STATES, stamp_ns, position, effort, controller.get_clock().now().nanoseconds
        )
        if time.perf_counter() - started > self._period:
            controller.counters.deadline_misses += 1
        self._pending = result
        if isinstance(result, Refusal):
            return result.message if result.chain_failed else None
        return result.torque

    def published(self) -> None:
        """Publishes what the topics loop would for the last answer, after its frame went out."""
        result, self._pending = self._pending, None
        if result is not None:
            self.controller.publish_result(result)

    def prepare(self) -> None:
        """The next step's work that needs no measurement (:meth:`ControllerCore.prepare`)."""
        self.controller.core.prepare()

    def forget(self) -> None:
        """After the preflight's rehearsal (stamped an hour ahead): the run starts afresh, its stamps too."""
        self._pending = None
        self.controller.core.reset()
        self.controller.core.admission.gate.reset()


def compose(
    context: Context, controller: dict[str, Any], bridge: dict[str, Any]
) -> tuple[ControllerNode, HwBridgeNode]:
    """The two nodes joined by the bridge's loop; ``controller`` and ``bridge``: their parameter overrides."""
    changes = ChangeBuffer()
    node = ControllerNode(changes=changes, context=context, parameter_overrides=controller)
    try:
        return node, HwBridgeNode(
            HostedController(node), changes, PROCESS_NAME, context=context, parameter_overrides=bridge
        )
    except ValueError:
        node.destroy_node()  # type: ignore[no-untyped-call]
        raise


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``direct_loop``: ``controller_node`` and ``hw_bridge_node`` in one executor."""
    changes = ChangeBuffer()
    hosted: list[HostedController] = []
    bridges: list[HwBridgeNode] = []

    def controller(context: Context) -> ControllerNode:
        node = ControllerNode(context=context, changes=changes)
        try:
            hosted.append(HostedController(node))
        except ValueError:
            node.destroy_node()  # type: ignore[no-untyped-call]
            raise
        return node

    def bridge(context: Context) -> HwBridgeNode:
        bridges.append(HwBridgeNode(hosted[0], changes, PROCESS_NAME, context=context))
        return bridges[0]

    def run() -> int:
        run_nodes([controller, bridge], args, nodes=(ControllerNode.NODE_NAME, HwBridgeNode.NODE_NAME))
        return judged_exit(0, bridges[0] if bridges else None, PROCESS_NAME)

    return refused(run, PROCESS_NAME)


if __name__ == "__main__":
    sys.exit(main())
