"""Whether an offline re-run reproduces a recording: bit for bit, or as far as another machine can.

The tolerance and its derivation are in docs/BAGS.md, "Rerun across machines"; docs/TESTING.md,
"Floats across machines", says which operation changes the last bits and how to force another path.
:class:`AgreementAccumulator` judges block by block (``smm-bag rerun`` streams); :func:`judge`, on arrays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from smm_analysis.runs.pairwise import PairwiseSum

__all__ = [
    "BIT_FOR_BIT",
    "CROSS_MACHINE",
    "LISTED_FLIPS",
    "Agreement",
    "AgreementAccumulator",
    "Tolerance",
    "allowed_difference",
    "judge",
    "tolerance_for",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Tolerance:
    """How far a re-run may be from the recording it re-runs.

    Attributes:
        relative: Per step and joint, |offline - recorded| <= relative * max|recorded| of that joint's
            series (commands and estimates), >= 0; 0 is bit for bit.
        flip_share: Isolated sign flips of the robust term allowed per joint, as a share of the steps
            (at least one when > 0), in [0, 1].
        index_relative: Relative tolerance of the torque indices (eps_u, du_rms) of the offline commands,
            flipped steps taken as recorded (a flip is counted once, as a flip), >= 0.
    """

    relative: float
    flip_share: float
    index_relative: float

    def __post_init__(self) -> None:
        for name in ("relative", "flip_share", "index_relative"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"{name} must be a finite number, got {value!r}")
            if value < 0.0:
                raise ValueError(f"{name} must be >= 0, got {value!r}")
        if self.flip_share > 1.0:
            raise ValueError(f"flip_share must be <= 1, got {self.flip_share!r}")

    def allowed_flips(self, steps: int) -> int:
        """Isolated flips allowed per joint in ``steps`` steps."""
        return 0 if self.flip_share == 0.0 else max(1, int(self.flip_share * steps))


#: What a bag recorded on another x86-64 machine passes (derivation: docs/BAGS.md, "Rerun across machines").
CROSS_MACHINE = Tolerance(relative=1e-9, flip_share=1e-3, index_relative=1e-6)
#: The claim within one machine and one numeric path: every bit equal, no flips.
BIT_FOR_BIT = Tolerance(relative=0.0, flip_share=0.0, index_relative=0.0)


def tolerance_for(relative: float | None) -> Tolerance:
    """``--tolerance``: None is :data:`CROSS_MACHINE`, 0 is :data:`BIT_FOR_BIT`, else its per-step part.

    Raises:
        ValueError: Negative or not finite.
    """
    if relative is None:
        return CROSS_MACHINE
    if relative == 0.0:
        return BIT_FOR_BIT
    return replace(CROSS_MACHINE, relative=relative)


LISTED_FLIPS = 1000
"""Sign-flip steps listed per joint (all are counted)."""


@dataclass(frozen=True)
class Agreement:
    """The verdict on one re-run, with what it rests on.

    Attributes:
        tolerance: The tolerance judged against.
        command_max_difference: Max |offline - recorded| command per joint, flips included (N m).
        command_allowed: The per-step tolerance per joint (N m).
        flip_steps: Per joint, the first :data:`LISTED_FLIPS` steps counted as isolated sign flips.
        flip_counts: Per joint, the steps counted as isolated sign flips.
        flips_allowed: Isolated flips allowed per joint.
        outside_counts: Per joint, steps out of tolerance that are not isolated flips.
        first_outside: Per joint, the first of them, or None.
        estimate_max_difference: Max |offline - recorded| estimate per joint (N m), or None.
        estimate_allowed: The per-step tolerance of the estimate per joint (N m), or None.
        index_relative_difference: Largest relative difference of eps_u and du_rms over the joints.
    """

    tolerance: Tolerance
    command_max_difference: tuple[float, float]
    command_allowed: tuple[float, float]
    flip_steps: tuple[tuple[int, ...], tuple[int, ...]]
    flip_counts: tuple[int, int]
    flips_allowed: int
    outside_counts: tuple[int, int]
    first_outside: tuple[int | None, int | None]
    estimate_max_difference: tuple[float, float] | None
    estimate_allowed: tuple[float, float] | None
    index_relative_difference: float

    @property
    def failures(self) -> tuple[str, ...]:
        """Why the re-run does not reproduce the recording; empty when it does."""
        reasons: list[str] = []
        for joint, name in enumerate(("alpha", "beta")):
            outside, first = self.outside_counts[joint], self.first_outside[joint]
            flips = self.flip_counts[joint]
            if outside and self.tolerance.flip_share == 0.0:
                reasons.append(f"{name}: {outside} step(s) differ (first at step {first})")
            elif outside:
                reasons.append(
                    f"{name}: {outside} step(s) differ by more than {self.command_allowed[joint]:.3g} "
                    f"N m and are not isolated sign flips (first at step {first})"
                )
            if flips > self.flips_allowed:
                reasons.append(f"{name}: {flips} sign flips, at most {self.flips_allowed} allowed")
            estimate, allowed = self.estimate_max_difference, self.estimate_allowed
            if estimate is not None and allowed is not None and estimate[joint] > allowed[joint]:
                reasons.append(
                    f"{name}: estimate differs by {estimate[joint]:.3g} N m (tolerance {allowed[joint]:.3g})"
                )
        if self.index_relative_difference > self.tolerance.index_relative:
            reasons.append(
                f"torque indices differ by {self.index_relative_difference:.3g} relative "
                f"(tolerance {self.tolerance.index_relative:g})"
            )
        return tuple(reasons)

    @property
    def ok(self) -> bool:
        """True when the re-run reproduces the recording within the tolerance."""
        return not self.failures


def allowed_difference(largest_recorded: FloatArray, tolerance: Tolerance) -> FloatArray:
    """Per-step tolerance per joint (N m) from the largest recorded |value| of each joint, shape (2,)."""
    return np.asarray(tolerance.relative * np.asarray(largest_recorded, dtype=np.float64), dtype=np.float64)


def _relative(a: float, b: float) -> float:
    return 0.0 if a == b else abs(a - b) / max(abs(a), abs(b))


class _TorqueIndices:
    """eps_u (eq. 45) and du_rms per joint of a torque series fed in blocks, bit for bit as on the whole.

    The terms are ``smm_analysis.metrics``' float operations, summed in numpy's order (:class:`PairwiseSum`).
    """

    def __init__(self, steps: int) -> None:
        self.steps = steps
        self.energy = [PairwiseSum(steps - 1) for _ in range(2)]
        self.increments = [PairwiseSum(steps - 1) for _ in range(2)]
        self._last: tuple[FloatArray, FloatArray] | None = None

    def add(self, t_s: FloatArray, torque: FloatArray) -> None:
        if self._last is not None:
            t_s, torque = np.concatenate([self._last[0], t_s]), np.vstack([self._last[1], torque])
        self._last = (t_s[-1:], torque[-1:])
        if t_s.size < 2:
            return
        squares = torque**2
        energy = 0.5 * (squares[1:] + squares[:-1]) * np.diff(t_s)[:, None]
        increments = np.diff(torque, axis=0) ** 2
        for joint in range(2):
            self.energy[joint].add(np.ascontiguousarray(energy[:, joint]))
            self.increments[joint].add(np.ascontiguousarray(increments[:, joint]))

    def values(self, joint: int) -> tuple[float, float]:
        """(eps_u, du_rms) of one joint."""
        return self.energy[joint].total(), math.sqrt(self.increments[joint].total() / (self.steps - 1))


@dataclass
class _Block:
    t_ns: NDArray[np.int64]
    command: FloatArray
    recorded: FloatArray
    difference: FloatArray
    out: NDArray[np.bool_]


class AgreementAccumulator:
    """:func:`judge` fed consecutive blocks of steps; holds one block (its last step needs the next one).

    The per-step tolerances come from the whole run's largest recorded values and the number of steps
    from a first pass; with them every figure is the one :func:`judge` gives on the whole arrays, bit for bit.

    Args:
        steps: Steps that will be added (>= 2).
        command_allowed: Per-step tolerance of the commands per joint (N m), shape (2,).
        flip_size: Largest change of one step's command a flip of the robust term makes, per joint (N m).
        tolerance: What is allowed.
        estimate_allowed: Per-step tolerance of the estimates (N m), shape (2,), or None: not judged.
    """

    def __init__(
        self,
        *,
        steps: int,
        command_allowed: FloatArray,
        flip_size: tuple[float, float],
        tolerance: Tolerance,
        estimate_allowed: FloatArray | None = None,
    ) -> None:
        self.tolerance = tolerance
        self.allowed = np.asarray(command_allowed, dtype=np.float64)
        self.flip_limit = np.asarray(flip_size) + self.allowed
        self.estimate_allowed = estimate_allowed
        self.difference_max = np.zeros(2)
        self.estimate_max = np.zeros(2)
        self.steps = 0
        self.t0: int | None = None
        self.last_ns = 0
        self.flips: tuple[list[int], list[int]] = ([], [])
        self.flip_counts = [0, 0]
        self.outside_counts = [0, 0]
        self.first_outside: list[int | None] = [None, None]
        self._previous_out = np.zeros(2, dtype=bool)
        self._pending: _Block | None = None
        self._offline, self._recorded = _TorqueIndices(steps), _TorqueIndices(steps)

    def add(
        self,
        t_ns: NDArray[np.int64],
        command: FloatArray,
        recorded_command: FloatArray,
        estimate: FloatArray | None = None,
        recorded_estimate: FloatArray | None = None,
    ) -> None:
        """Adds the next steps: stamps (ns), shape (n,); commands and estimates (N m), shape (n, 2)."""
        if t_ns.size == 0:
            return
        if self.t0 is None:
            self.t0 = int(t_ns[0])
        difference = np.abs(command - recorded_command)
        self.difference_max = np.maximum(self.difference_max, np.max(difference, axis=0))
        if estimate is not None and recorded_estimate is not None:
            estimate_difference = np.max(np.abs(estimate - recorded_estimate), axis=0)
            self.estimate_max = np.maximum(self.estimate_max, estimate_difference)
        out = difference > self.allowed
        if self._pending is not None:
            self._settle(out[0])
        self._pending = _Block(t_ns, command, recorded_command, difference, out)

    def _settle(self, next_out: NDArray[np.bool_]) -> None:
        """Classifies the held block's steps (the next step's flags known) and sums its indices."""
        block = self._pending
        assert block is not None and self.t0 is not None
        self._pending = None
        out = block.out
        near = np.zeros_like(out)
        near[1:] |= out[:-1]
        near[:-1] |= out[1:]
        near[0] |= self._previous_out
        near[-1] |= next_out
        is_flip = out & ~near & (block.difference <= self.flip_limit) & (self.tolerance.flip_share > 0.0)
        for joint in range(2):
            flips = np.flatnonzero(is_flip[:, joint])
            self.flip_counts[joint] += int(flips.size)
            room = LISTED_FLIPS - len(self.flips[joint])
            self.flips[joint].extend(int(k) + self.steps for k in flips[:room])
            outside = np.flatnonzero(out[:, joint] & ~is_flip[:, joint])
            self.outside_counts[joint] += int(outside.size)
            if outside.size and self.first_outside[joint] is None:
                self.first_outside[joint] = int(outside[0]) + self.steps
        unflipped = np.where(is_flip, block.recorded, block.command)
        t_s = (block.t_ns - self.t0).astype(np.float64) / 1e9
        self._offline.add(t_s, unflipped)
        self._recorded.add(t_s, block.recorded)
        self._previous_out = out[-1]
        self.steps += block.t_ns.size
        self.last_ns = int(block.t_ns[-1])

    def result(self) -> Agreement:
        """The verdict on the steps added."""
        if self._pending is not None:
            self._settle(np.zeros(2, dtype=bool))
        index_difference = 0.0
        for joint in range(2):
            pairs = zip(self._offline.values(joint), self._recorded.values(joint), strict=True)
            index_difference = max(index_difference, *(_relative(a, b) for a, b in pairs))
        estimate_max, estimate_allowed = None, None
        if self.estimate_allowed is not None:
            estimate_max, estimate_allowed = _pair(self.estimate_max), _pair(self.estimate_allowed)
        return Agreement(
            tolerance=self.tolerance,
            command_max_difference=_pair(self.difference_max),
            command_allowed=_pair(self.allowed),
            flip_steps=(tuple(self.flips[0]), tuple(self.flips[1])),
            flip_counts=(self.flip_counts[0], self.flip_counts[1]),
            flips_allowed=self.tolerance.allowed_flips(self.steps),
            outside_counts=(self.outside_counts[0], self.outside_counts[1]),
            first_outside=(self.first_outside[0], self.first_outside[1]),
            estimate_max_difference=estimate_max,
            estimate_allowed=estimate_allowed,
            index_relative_difference=index_difference,
        )


def judge(
    t_ns: NDArray[np.int64],
    command: FloatArray,
    recorded_command: FloatArray,
    *,
    flip_size: tuple[float, float],
    tolerance: Tolerance,
    estimate: FloatArray | None = None,
    recorded_estimate: FloatArray | None = None,
) -> Agreement:
    """Judges offline commands (and estimates) against the recorded ones.

    A step of joint j whose difference exceeds the per-step tolerance but not ``flip_size[j]`` (plus the
    tolerance), with both neighbouring steps within the tolerance, is an isolated sign flip (none are
    counted when the tolerance allows none: every differing step is then reported as such).

    Args:
        t_ns: Stamps (ns), shape (N,), N >= 2.
        command: Offline commands (N m), shape (N, 2).
        recorded_command: Recorded commands (N m), shape (N, 2).
        flip_size: Largest change of one step's command a flip of the robust term makes, per joint
            (N m, 2 b_d for a pure sign; 0 where the law has no discontinuity).
        tolerance: What is allowed.
        estimate: Offline disturbance estimates (N m), shape (N, 2), or None.
        recorded_estimate: Recorded estimates, shape (N, 2), or None.
    """
    judged = estimate is not None and recorded_estimate is not None
    accumulator = AgreementAccumulator(
        steps=int(t_ns.size),
        command_allowed=allowed_difference(np.max(np.abs(recorded_command), axis=0, initial=0.0), tolerance),
        flip_size=flip_size,
        tolerance=tolerance,
        estimate_allowed=(
            allowed_difference(np.max(np.abs(recorded_estimate), axis=0, initial=0.0), tolerance)
            if judged and recorded_estimate is not None
            else None
        ),
    )
    accumulator.add(t_ns, command, recorded_command, estimate, recorded_estimate)
    return accumulator.result()


def _pair(values: FloatArray) -> tuple[float, float]:
    return float(values[0]), float(values[1])
