"""Time the conversions (run by ``make bench``); prints microseconds per call.

The lockstep graph converts about 12 messages per 1 kHz step in one process and must reach 2000 steps/s, so
each conversion should cost about 5-10 microseconds. This only prints figures; nothing asserts on wall-clock
time.
"""

from __future__ import annotations

import timeit
from collections.abc import Callable

import numpy as np
from smm_msgs_py.conversions import (
    JointSample,
    clock_msg,
    internals_to_msg,
    joint_state_to_sample,
    labelled_to_msg,
    msg_to_labelled,
    msg_to_reference,
    msg_to_torque,
    reference_to_msg,
    sample_to_joint_state,
    torque_to_msg,
)
from smm_msgs_py.layouts import DISTURBANCE_ESTIMATE_ROWS, OBSERVER_STATE_ROWS

from smm_node_runtime import COUNTER_ROWS

STAMP_NS = 1_700_000_000_123_456_789
INTERNALS_ROWS = ("kp", "kd", "u", "feedforward", "feedback", "disturbance", "robust", "tau")


def _read_only(values: list[float]) -> np.ndarray:
    frozen = np.array(values, dtype=np.float64)
    frozen.flags.writeable = False
    return frozen


def cases() -> dict[str, Callable[[], object]]:
    """Return the timed calls, each on a representative valid input (as the nodes pass them)."""
    tau = np.array([1.25, -0.5])
    position = np.array([0.1, 0.2])
    reference = np.arange(6.0).reshape(3, 2)
    observer = np.ones((len(OBSERVER_STATE_ROWS), 2))
    estimate = np.ones((len(DISTURBANCE_ESTIMATE_ROWS), 2))
    # An algorithm's internals (read-only copies) merged with the node counters, as the nodes publish them.
    internals = {name: _read_only([index, -index]) for index, name in enumerate(INTERNALS_ROWS)}
    internals |= {name: np.full(2, 0.0) for name in COUNTER_ROWS}
    sample = JointSample(STAMP_NS, position, np.array([1.0, 2.0]), np.array([3.0, 4.0]))
    measurement = sample_to_joint_state(JointSample(STAMP_NS, position, None, tau))
    swapped = sample_to_joint_state(JointSample(STAMP_NS, position, None, tau))
    swapped.name = ["beta", "alpha"]
    torque_msg = torque_to_msg(tau, STAMP_NS)
    reference_msg = reference_to_msg(reference, STAMP_NS)
    observer_msg = labelled_to_msg(observer, OBSERVER_STATE_ROWS, STAMP_NS)
    estimate_msg = labelled_to_msg(estimate, DISTURBANCE_ESTIMATE_ROWS, STAMP_NS)
    return {
        "joint_state_to_sample (alpha, beta)": lambda: joint_state_to_sample(
            measurement, require_effort=True
        ),
        "joint_state_to_sample (beta, alpha)": lambda: joint_state_to_sample(swapped, require_effort=True),
        "JointSample (position, effort)": lambda: JointSample(STAMP_NS, position, None, tau),
        "sample_to_joint_state (3 fields)": lambda: sample_to_joint_state(sample),
        "clock_msg": lambda: clock_msg(STAMP_NS),
        "torque_to_msg": lambda: torque_to_msg(tau, STAMP_NS),
        "msg_to_torque": lambda: msg_to_torque(torque_msg),
        "reference_to_msg": lambda: reference_to_msg(reference, STAMP_NS),
        "msg_to_reference": lambda: msg_to_reference(reference_msg),
        "labelled_to_msg (disturbance estimate)": lambda: labelled_to_msg(
            estimate, DISTURBANCE_ESTIMATE_ROWS, STAMP_NS
        ),
        "labelled_to_msg (4 rows)": lambda: labelled_to_msg(observer, OBSERVER_STATE_ROWS, STAMP_NS),
        "msg_to_labelled (4 rows)": lambda: msg_to_labelled(observer_msg),
        "msg_to_labelled (disturbance estimate, expected rows)": lambda: msg_to_labelled(
            estimate_msg, expected_rows=DISTURBANCE_ESTIMATE_ROWS
        ),
        "internals_to_msg (+ counters)": lambda: internals_to_msg(internals, STAMP_NS),
    }


def lockstep_step() -> Callable[[], object]:
    """Return the conversions of one lockstep step of the graph (sim, TD, reference, FLESO, controller).

    Per step: the simulator publishes /clock, the measurement and the ground truth and parses the torque;
    the TD, reference, FLESO and controller parse their inputs and publish their outputs and internals.
    """
    calls = cases()
    parse_measurement = calls["joint_state_to_sample (alpha, beta)"]
    return lambda: (
        calls["clock_msg"](),
        calls["JointSample (position, effort)"](),
        calls["sample_to_joint_state (3 fields)"](),  # measurement
        calls["sample_to_joint_state (3 fields)"](),  # ground truth
        calls["msg_to_torque"](),
        parse_measurement(),  # TD
        calls["JointSample (position, effort)"](),
        calls["sample_to_joint_state (3 fields)"](),  # filtered
        parse_measurement(),  # reference
        calls["reference_to_msg"](),
        parse_measurement(),  # FLESO: filtered and measurement
        parse_measurement(),
        calls["labelled_to_msg (disturbance estimate)"](),  # disturbance estimate
        calls["labelled_to_msg (4 rows)"](),  # observer state
        parse_measurement(),  # controller: filtered, reference, estimate
        calls["msg_to_reference"](),
        calls["msg_to_labelled (disturbance estimate, expected rows)"](),
        calls["torque_to_msg"](),
        *(calls["internals_to_msg (+ counters)"]() for _ in range(4)),  # TD, reference, FLESO, controller
    )


def main(calls: int = 20_000) -> None:
    """Print the best of 5 runs of ``calls`` calls of each case, in microseconds per call."""
    total = 0.0
    for name, call in cases().items():
        seconds = min(timeit.repeat(call, number=calls, repeat=5)) / calls
        total += seconds
        print(f"{name:40s} {seconds * 1e6:7.2f} us")
    print(f"{'sum of the cases above':40s} {total * 1e6:7.2f} us")
    step_seconds = min(timeit.repeat(lockstep_step(), number=calls // 10, repeat=5)) / (calls // 10)
    print(f"{'conversions of one lockstep step':40s} {step_seconds * 1e6:7.2f} us (budget of a step: 500 us)")


if __name__ == "__main__":
    main()
