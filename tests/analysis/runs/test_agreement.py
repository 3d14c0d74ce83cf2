"""Agreement of a re-run with its recording: tight per step, isolated sign flips counted, bit for bit at 0."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_analysis.runs.agreement import BIT_FOR_BIT, CROSS_MACHINE, Tolerance, judge, tolerance_for
from smm_analysis.runs.rerun import chain_settings
from smm_bag.cli import main
from smm_bag.exit_codes import EXIT_USAGE

STEPS = 2000
T_NS = np.arange(STEPS, dtype=np.int64) * 1_000_000
FLIP = chain_settings({}, "fpdeso").flip_size  # 2 b_d per joint (N m)


def _recorded() -> np.ndarray:
    t = T_NS / 1e9
    return np.column_stack([3.0 * np.sin(2.0 * np.pi * t) + 0.5, -2.0 * np.cos(3.0 * np.pi * t)])


def _ulps(values: np.ndarray, count: int) -> np.ndarray:
    for _ in range(count):
        values = np.nextafter(values, np.inf)
    return values


def test_flip_size_is_two_b_d_for_the_pure_sign_and_zero_for_a_continuous_law() -> None:
    assert pytest.approx((0.06 * np.pi, 0.04 * np.pi)) == FLIP
    layered = chain_settings({"fpdeso.boundary_layer": [0.0, 0.01]}, "fpdeso")
    assert layered.flip_size == pytest.approx((0.06 * np.pi, 0.0))
    assert chain_settings({}, "fpd").flip_size == (0.0, 0.0)


def test_last_bit_differences_pass_the_default_and_fail_bit_for_bit() -> None:
    recorded = _recorded()
    offline = _ulps(recorded, 20)
    default = judge(T_NS, offline, recorded, flip_size=FLIP, tolerance=CROSS_MACHINE)
    assert default.ok and default.flip_steps == ((), ())
    assert default.command_max_difference[0] > 0.0
    exact = judge(T_NS, offline, recorded, flip_size=FLIP, tolerance=BIT_FOR_BIT)
    assert not exact.ok
    assert exact.failures[0] == f"alpha: {STEPS} step(s) differ (first at step 0)"
    assert judge(T_NS, recorded.copy(), recorded, flip_size=FLIP, tolerance=BIT_FOR_BIT).ok


@given(
    st.lists(
        st.integers(0, STEPS - 1), min_size=1, max_size=CROSS_MACHINE.allowed_flips(STEPS), unique=True
    ).filter(lambda steps: all(abs(a - b) > 1 for a in steps for b in steps if a != b)),
    st.sampled_from([1.0, 2.0]),
    st.integers(0, 1),
)
def test_isolated_flips_within_the_budget_pass_and_are_counted(
    steps: list[int], size: float, joint: int
) -> None:
    recorded = _recorded()
    offline = _ulps(recorded, 5)
    offline[steps, joint] += size * FLIP[joint] / 2.0 * np.where(np.array(steps) % 2 == 0, 1.0, -1.0)
    agreement = judge(T_NS, offline, recorded, flip_size=FLIP, tolerance=CROSS_MACHINE)
    assert agreement.ok, agreement.failures
    assert agreement.flip_steps[joint] == tuple(sorted(steps)) and agreement.flip_steps[1 - joint] == ()
    assert agreement.command_max_difference[joint] == pytest.approx(size * FLIP[joint] / 2.0)
    assert agreement.index_relative_difference < CROSS_MACHINE.index_relative


def test_adjacent_flips_too_many_flips_and_larger_jumps_fail() -> None:
    recorded = _recorded()
    adjacent = recorded.copy()
    adjacent[100:102, 0] += FLIP[0]
    failures = judge(T_NS, adjacent, recorded, flip_size=FLIP, tolerance=CROSS_MACHINE).failures
    assert failures[0] == (
        "alpha: 2 step(s) differ by more than 3.5e-09 N m and are not isolated sign flips (first at step 100)"
    )
    assert failures[1].startswith("torque indices differ by ")
    many = recorded.copy()
    many[10:1000:10, 1] -= FLIP[1]
    failures = judge(T_NS, many, recorded, flip_size=FLIP, tolerance=CROSS_MACHINE).failures
    assert failures == ("beta: 99 sign flips, at most 2 allowed",)  # flipped steps: not in the indices
    jump = recorded.copy()
    jump[500, 0] += 1.01 * FLIP[0]
    assert not judge(T_NS, jump, recorded, flip_size=FLIP, tolerance=CROSS_MACHINE).ok
    assert not judge(T_NS, jump, recorded, flip_size=(0.0, 0.0), tolerance=CROSS_MACHINE).ok


def test_a_bias_within_a_loose_step_tolerance_fails_on_the_indices() -> None:
    recorded = _recorded()
    loose = tolerance_for(1e-3)
    assert loose.flip_share == CROSS_MACHINE.flip_share
    assert loose.index_relative == CROSS_MACHINE.index_relative
    agreement = judge(T_NS, recorded + 1e-4, recorded, flip_size=FLIP, tolerance=loose)
    assert agreement.outside_counts == (0, 0)
    assert agreement.failures[-1].startswith("torque indices differ by ")


def test_estimates_are_judged_without_flips() -> None:
    recorded = _recorded()
    estimate = recorded / 10.0
    moved = estimate.copy()
    moved[7, 1] += 1e-6
    agreement = judge(
        T_NS,
        recorded,
        recorded,
        flip_size=FLIP,
        tolerance=CROSS_MACHINE,
        estimate=moved,
        recorded_estimate=estimate,
    )
    assert agreement.failures == ("beta: estimate differs by 1e-06 N m (tolerance 2e-10)",)


def test_tolerance_for_and_validation() -> None:
    assert tolerance_for(None) is CROSS_MACHINE and tolerance_for(0.0) is BIT_FOR_BIT
    assert tolerance_for(1e-6).relative == 1e-6
    assert BIT_FOR_BIT.allowed_flips(10**6) == 0 and CROSS_MACHINE.allowed_flips(10) == 1
    assert CROSS_MACHINE.allowed_flips(STEPS) == 2
    with pytest.raises(ValueError, match="relative must be >= 0"):
        tolerance_for(-1.0)
    with pytest.raises(ValueError, match="flip_share must be <= 1"):
        Tolerance(0.0, 2.0, 0.0)
    with pytest.raises(ValueError, match="index_relative must be a finite number"):
        Tolerance(0.0, 0.0, float("nan"))


def test_a_negative_tolerance_is_a_usage_error_before_the_bag_is_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["rerun", str(tmp_path / "absent"), "--tolerance=-1e-9"]) == EXIT_USAGE
    assert "--tolerance: relative must be >= 0, got -1e-09" in capsys.readouterr().err
