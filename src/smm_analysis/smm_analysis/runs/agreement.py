"""Whether an offline re-run reproduces a recording: bit for bit, or as far as another machine can.

The tolerance and its derivation are in docs/BAGS.md, "Rerun across machines"; docs/TESTING.md,
"Floats across machines", says which operation changes the last bits and how to force another path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from smm_analysis.metrics import control_energy, torque_increment_rms

__all__ = ["BIT_FOR_BIT", "CROSS_MACHINE", "Agreement", "Tolerance", "judge", "tolerance_for"]

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


@dataclass(frozen=True)
class Agreement:
    """The verdict on one re-run, with what it rests on.

    Attributes:
        tolerance: The tolerance judged against.
        command_max_difference: Max |offline - recorded| command per joint, flips included (N m).
        command_allowed: The per-step tolerance per joint (N m).
        flip_steps: Per joint, the steps counted as isolated sign flips.
        flips_allowed: Isolated flips allowed per joint.
        outside: Per joint, steps out of tolerance that are not isolated flips.
        estimate_max_difference: Max |offline - recorded| estimate per joint (N m), or None.
        estimate_allowed: The per-step tolerance of the estimate per joint (N m), or None.
        index_relative_difference: Largest relative difference of eps_u and du_rms over the joints.
    """

    tolerance: Tolerance
    command_max_difference: tuple[float, float]
    command_allowed: tuple[float, float]
    flip_steps: tuple[tuple[int, ...], tuple[int, ...]]
    flips_allowed: int
    outside: tuple[tuple[int, ...], tuple[int, ...]]
    estimate_max_difference: tuple[float, float] | None
    estimate_allowed: tuple[float, float] | None
    index_relative_difference: float

    @property
    def failures(self) -> tuple[str, ...]:
        """Why the re-run does not reproduce the recording; empty when it does."""
        reasons: list[str] = []
        for joint, name in enumerate(("alpha", "beta")):
            outside, flips = self.outside[joint], self.flip_steps[joint]
            if outside and self.tolerance.flip_share == 0.0:
                reasons.append(f"{name}: {len(outside)} step(s) differ (first at step {outside[0]})")
            elif outside:
                reasons.append(
                    f"{name}: {len(outside)} step(s) differ by more than {self.command_allowed[joint]:.3g} "
                    f"N m and are not isolated sign flips (first at step {outside[0]})"
                )
            if len(flips) > self.flips_allowed:
                reasons.append(f"{name}: {len(flips)} sign flips, at most {self.flips_allowed} allowed")
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


def _allowed(recorded: FloatArray, relative: float) -> FloatArray:
    return np.asarray(relative * np.max(np.abs(recorded), axis=0, initial=0.0), dtype=np.float64)


def _relative(a: float, b: float) -> float:
    return 0.0 if a == b else abs(a - b) / max(abs(a), abs(b))


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
    difference = np.abs(command - recorded_command)
    allowed = _allowed(recorded_command, tolerance.relative)
    out = difference > allowed
    near = np.zeros_like(out)
    near[1:] |= out[:-1]
    near[:-1] |= out[1:]
    is_flip = out & ~near & (difference <= np.asarray(flip_size) + allowed) & (tolerance.flip_share > 0.0)
    unflipped = np.where(is_flip, recorded_command, command)
    index_difference = 0.0
    for joint in range(2):
        for index in (
            lambda series: control_energy(t_ns, series),
            torque_increment_rms,
        ):
            index_difference = max(
                index_difference,
                _relative(index(unflipped[:, joint]), index(recorded_command[:, joint])),
            )
    estimate_max: tuple[float, float] | None = None
    estimate_allowed: tuple[float, float] | None = None
    if estimate is not None and recorded_estimate is not None:
        estimate_max = _pair(np.max(np.abs(estimate - recorded_estimate), axis=0, initial=0.0))
        estimate_allowed = _pair(_allowed(recorded_estimate, tolerance.relative))
    return Agreement(
        tolerance=tolerance,
        command_max_difference=_pair(np.max(difference, axis=0, initial=0.0)),
        command_allowed=_pair(allowed),
        flip_steps=(_steps(is_flip[:, 0]), _steps(is_flip[:, 1])),
        flips_allowed=tolerance.allowed_flips(int(t_ns.size)),
        outside=(_steps(out[:, 0] & ~is_flip[:, 0]), _steps(out[:, 1] & ~is_flip[:, 1])),
        estimate_max_difference=estimate_max,
        estimate_allowed=estimate_allowed,
        index_relative_difference=index_difference,
    )


def _pair(values: FloatArray) -> tuple[float, float]:
    return float(values[0]), float(values[1])


def _steps(mask: NDArray[np.bool_]) -> tuple[int, ...]:
    return tuple(int(k) for k in np.flatnonzero(mask))
