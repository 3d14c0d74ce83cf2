"""Dimension names and row labels of the labelled ``Float64MultiArray`` messages.

A dimension label reads ``<dimname>:<comma-separated item names>`` (e.g. ``joint:alpha,beta``); the last
dimension of every array we publish is ``stamp_ns:<int>`` with size 1 (see ``docs/INTERFACES.md``).
"""

from typing import Final

JOINT_DIM: Final[str] = "joint"
"""Name of the column dimension (items: the joint names)."""

ORDER_DIM: Final[str] = "order"
"""Name of the row dimension of a reference (items: :data:`REFERENCE_ROWS`)."""

QUANTITY_DIM: Final[str] = "quantity"
"""Name of the row dimension of a generic labelled array (items: named quantities)."""

STAMP_DIM: Final[str] = "stamp_ns"
"""Name of the trailing size-1 dimension that carries the stamp of the answered measurement."""

DIM_SEPARATOR: Final[str] = ":"
ITEM_SEPARATOR: Final[str] = ","

REFERENCE_ROWS: Final[tuple[str, str, str]] = ("position", "velocity", "acceleration")
"""Rows of a reference: position (rad), velocity (rad/s), acceleration (rad/s^2)."""

DISTURBANCE_ESTIMATE_ROWS: Final[tuple[str, str]] = ("xi_tilde", "x2_hat")
"""Rows of the disturbance estimate: lumped disturbance estimate xi~ (N m) and the observer's velocity
estimate x2^ (rad/s), which FPDESO's law uses with ``velocity_source: observer``."""

OBSERVER_STATE_ROWS: Final[tuple[str, str, str, str]] = ("x1_hat", "x2_hat", "x3_hat", "bandwidth")
"""Rows of the observer state: x1_hat (rad), x2_hat (rad/s), x3_hat (rad/s^2), bandwidth (rad/s)."""
