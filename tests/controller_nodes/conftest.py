"""Fixtures of the node tests (the rig itself is in ``controller_nodes.node_rig``)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest
from controller_nodes.node_rig import Rig


@pytest.fixture
def make_rig(ros_context: Any) -> Iterator[Callable[..., Rig]]:
    """Factory ``make_rig(*nodes)``; every rig is closed at teardown."""
    rigs: list[Rig] = []

    def factory(*nodes: Any) -> Rig:
        rig = Rig(ros_context, nodes)
        rigs.append(rig)
        return rig

    yield factory
    for rig in rigs:
        rig.close()
