"""Time the conversions (run by ``make bench``); prints microseconds per call.

The control loop converts several messages per 1 kHz step, so each conversion should cost tens of
microseconds at most. This only prints figures; nothing asserts on wall-clock time.
"""

from __future__ import annotations

import timeit
from collections.abc import Callable

import numpy as np
from smm_msgs_py.conversions import (
    JointSample,
    joint_state_to_sample,
    labelled_to_msg,
    msg_to_labelled,
    msg_to_reference,
    msg_to_torque,
    reference_to_msg,
    sample_to_joint_state,
    torque_to_msg,
)
from smm_msgs_py.layouts import OBSERVER_STATE_ROWS

STAMP_NS = 1_700_000_000_123_456_789


def cases() -> dict[str, Callable[[], object]]:
    """Return the timed calls, each on a representative valid input."""
    tau = np.array([1.25, -0.5])
    reference = np.arange(6.0).reshape(3, 2)
    observer = np.ones((len(OBSERVER_STATE_ROWS), 2))
    sample = JointSample(STAMP_NS, np.array([0.1, 0.2]), np.array([1.0, 2.0]), np.array([3.0, 4.0]))
    measurement = sample_to_joint_state(JointSample(STAMP_NS, np.array([0.1, 0.2]), None, tau))
    swapped = sample_to_joint_state(JointSample(STAMP_NS, np.array([0.1, 0.2]), None, tau))
    swapped.name = ["beta", "alpha"]
    torque_msg = torque_to_msg(tau, STAMP_NS)
    reference_msg = reference_to_msg(reference, STAMP_NS)
    observer_msg = labelled_to_msg(observer, OBSERVER_STATE_ROWS, STAMP_NS)
    return {
        "joint_state_to_sample (alpha, beta)": lambda: joint_state_to_sample(
            measurement, require_effort=True
        ),
        "joint_state_to_sample (beta, alpha)": lambda: joint_state_to_sample(swapped, require_effort=True),
        "sample_to_joint_state (3 fields)": lambda: sample_to_joint_state(sample),
        "torque_to_msg": lambda: torque_to_msg(tau, STAMP_NS),
        "msg_to_torque": lambda: msg_to_torque(torque_msg),
        "reference_to_msg": lambda: reference_to_msg(reference, STAMP_NS),
        "msg_to_reference": lambda: msg_to_reference(reference_msg),
        "labelled_to_msg (4 rows)": lambda: labelled_to_msg(observer, OBSERVER_STATE_ROWS, STAMP_NS),
        "msg_to_labelled (4 rows)": lambda: msg_to_labelled(observer_msg),
    }


def main(calls: int = 20_000) -> None:
    """Print the best of 5 runs of ``calls`` calls of each case, in microseconds per call."""
    for name, call in cases().items():
        seconds = min(timeit.repeat(call, number=calls, repeat=5)) / calls
        print(f"{name:40s} {seconds * 1e6:7.2f} us")


if __name__ == "__main__":
    main()
