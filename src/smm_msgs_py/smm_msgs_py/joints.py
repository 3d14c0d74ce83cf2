"""Joint names of the 2-DOF SMM, in the order every array of the stack uses."""

from typing import Final

JOINT_NAMES: Final[tuple[str, str]] = ("alpha", "beta")
"""Joint order of every per-joint array, shape (2,): index 0 is ``alpha``, index 1 is ``beta``."""

NUM_JOINTS: Final[int] = len(JOINT_NAMES)
