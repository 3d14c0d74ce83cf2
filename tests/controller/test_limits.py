"""Limits around the law (smm_controller.limits): plausibility, torque and rate limits, PID anti-windup."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_controller.baselines import PIDConfig, PIDController
from smm_controller.chain import make_chain
from smm_controller.laws import PAPER_LAWS
from smm_controller.limits import (
    DEFAULT_TORQUE_LIMIT,
    MECHANICAL_STOPS,
    MeasurementLimits,
    OutputLimitConfig,
    OutputLimiter,
    PlausibilityCheck,
    track_saturation,
)
from smm_sim.plant import PlantConfig

from smm_dynamics import SMMParameters

MS = 1_000_000
REFERENCE = [[0.5, -0.3], [0.0, 0.0], [0.0, 0.0]]


def test_the_default_range_is_the_simulators_stops_plus_a_margin_below_the_singularity() -> None:
    assert PlantConfig().joint_limits == MECHANICAL_STOPS
    limits = MeasurementLimits()
    assert all(
        stop < bound < math.pi / 2
        for stop, bound in zip(MECHANICAL_STOPS, limits.position_limit, strict=True)
    )


@pytest.mark.parametrize("position", [(1.6, 0.0), (0.0, -1.6), (100.0, 100.0), (1e300, 0.2)])
def test_a_position_outside_the_range_is_implausible(position: tuple[float, float]) -> None:
    assert "outside" in (PlausibilityCheck().reason(position, 0, MS) or "")


def test_a_move_faster_than_max_speed_is_implausible_and_the_allowance_grows_with_the_gap() -> None:
    check = PlausibilityCheck(MeasurementLimits(max_speed=(100.0, 100.0)))
    assert check.reason((0.0, 0.0), 0, MS) is None
    check.accept((0.0, 0.0), 0)
    assert check.reason((0.09, -0.09), MS, MS) is None
    assert "faster than" in (check.reason((0.5, 0.0), MS, MS) or "")
    assert check.reason((0.5, 0.0), MS, 10 * MS) is None  # at 100 Hz one period allows 1 rad
    assert check.reason((0.5, 0.0), 5 * MS, MS) is None  # five periods later it is a plausible move
    check.reset()
    assert check.reason((0.5, 0.0), MS, MS) is None


def test_the_torque_limit_clamps_each_joint_and_shows_in_the_internals() -> None:
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(10.0, 20.0)))
    assert limiter.limit_floats((15.0, -25.0), 1e-3) == (10.0, -20.0)
    internals = limiter.internals
    np.testing.assert_array_equal(internals["tau_unlimited"], [15.0, -25.0])
    np.testing.assert_array_equal(internals["tau"], [10.0, -20.0])
    np.testing.assert_array_equal(internals["clamped"], [1.0, 1.0])
    assert limiter.limit_floats((5.0, 19.0), 1e-3) == (5.0, 19.0)
    np.testing.assert_array_equal(limiter.internals["clamped"], [0.0, 0.0])
    np.testing.assert_array_equal(limiter.internals["clamps"], [1.0, 1.0])


def test_the_rate_limit_bounds_the_change_per_step() -> None:
    limiter = OutputLimiter(OutputLimitConfig(rate_limit=(1000.0, math.inf)))
    assert limiter.limit_floats((0.0, 0.0), 1e-3) == (0.0, 0.0)
    assert limiter.limit_floats((50.0, 50.0), 1e-3) == (1.0, 50.0)
    assert limiter.limit_floats((50.0, 50.0), 1e-3) == (2.0, 50.0)


def test_a_non_finite_law_output_is_not_turned_into_a_finite_torque() -> None:
    limiter = OutputLimiter()
    tau = limiter.limit_floats((math.inf, math.nan), 1e-3)
    assert math.isinf(tau[0])
    assert math.isnan(tau[1])


def _clamped(value: float, low: float, high: float) -> float:
    """The limiter's clamp written plainly: min/max of a finite value; a non-finite one passes."""
    return min(max(value, low), high) if math.isfinite(value) else value


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.tuples(st.floats(width=64), st.floats(width=64)), min_size=1, max_size=20),
    st.tuples(st.floats(0.1, 1e3), st.floats(0.1, 1e3)),
    st.tuples(st.floats(1.0, 1e6), st.floats(1.0, 1e6)),
)
def test_the_limited_torque_is_the_rate_then_magnitude_clamp_bit_for_bit(
    taus: list[tuple[float, float]], bounds: tuple[float, float], rates: tuple[float, float]
) -> None:
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=bounds, rate_limit=rates))
    previous: tuple[float, ...] | None = None
    for tau in taus:
        expected = []
        for joint in range(2):
            value = tau[joint]
            if previous is not None:
                step = rates[joint] * 1e-3
                value = _clamped(value, previous[joint] - step, previous[joint] + step)
            expected.append(_clamped(value, -bounds[joint], bounds[joint]))
        out = limiter.limit_floats(tau, 1e-3)
        assert [v.hex() for v in out] == [v.hex() for v in expected]  # NaN and signed zeros too
        previous = out


@settings(max_examples=100, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(min_value=-1e6, max_value=1e6, allow_subnormal=False),
            st.floats(min_value=-1e6, max_value=1e6, allow_subnormal=False),
        ),
        min_size=1,
        max_size=30,
    )
)
def test_no_limited_output_exceeds_either_limit(taus: list[tuple[float, float]]) -> None:
    config = OutputLimitConfig(torque_limit=(30.0, 40.0), rate_limit=(5000.0, 8000.0))
    limiter = OutputLimiter(config)
    previous = None
    for tau in taus:
        out = limiter.limit_floats(tau, 1e-3)
        for joint in range(2):
            assert abs(out[joint]) <= config.torque_limit[joint]
            if previous is not None:
                assert abs(out[joint] - previous[joint]) <= config.rate_limit[joint] * 1e-3 * (1 + 1e-12)
        previous = out


@pytest.mark.parametrize("name", PAPER_LAWS)
def test_the_chain_applies_the_default_torque_limit_to_absurd_measurements(name: str) -> None:
    chain = make_chain(name, SMMParameters())
    chain.step((0.0, 0.0), (0.0, 0.0), REFERENCE, 1e-3)
    clamped = np.zeros(2)
    for _ in range(50):  # the (100, 100) rad gave -670 / -890 N m
        tau = chain.step((100.0, -100.0), (0.0, 0.0), REFERENCE, 1e-3)
        assert np.all(np.abs(tau) <= DEFAULT_TORQUE_LIMIT)
        clamped = np.maximum(clamped, chain.internals["limiter.clamped"])
    np.testing.assert_array_equal(clamped, [1.0, 1.0])


def windup(limited: bool, seconds: float = 20.0) -> PIDController:
    """A PID whose output is held at 5 N m while a 1 rad error persists, then the error reverses."""
    pid = PIDController(PIDConfig())
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(5.0, 5.0)))
    dt = 1e-3
    for _ in range(round(seconds / dt)):
        tau = pid.step_floats([[1.0, 1.0], [0.0, 0.0], [0.0, 0.0]], (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), dt)
        out = limiter.limit_floats(tau, dt)
        if limited:
            track_saturation(pid, tau, out, dt)
    return pid


def test_back_calculation_stops_the_pid_integrator_winding_up_while_clamped() -> None:
    free = windup(limited=False)
    tracked = windup(limited=True)
    # Without back-calculation the integral grows with ki * t (0.9 * 20 = 18 N m on alpha, 60 on beta).
    assert free.internals["i"][0] > 15.0
    assert free.internals["i"][1] > 50.0
    # With it, the law's own output settles at the limit plus ki * T_t * e (1.16 / 1.22 N m here).
    assert np.all(tracked.internals["tau"] < 5.0 + 1.5)
    assert np.all(free.internals["tau"] > 25.0)


def test_the_reproduced_scenarios_stay_below_the_default_limit() -> None:
    """The reproduction runs with the default limit and never reaches it (largest command 288 N m)."""
    from smm_analysis.closed_loop import run_closed_loop

    run = run_closed_loop("step", "fpdeso", record_internals=False)
    peak = np.abs(np.asarray(run.command_torque)).max(axis=0)
    assert np.all(peak < DEFAULT_TORQUE_LIMIT)
    assert peak.max() > 0.9 * DEFAULT_TORQUE_LIMIT[0]  # the limit sits just above the largest command


def test_the_refusal_names_the_joint_its_value_and_the_bound() -> None:
    limits = MeasurementLimits(position_limit=(1.0, 2.0))
    assert PlausibilityCheck(limits).reason((0.5, -2.5), 0, MS) == "position[1] = -2.5 rad outside +-2.0 rad"
    assert PlausibilityCheck(limits).reason((1.25, 0.0), 0, MS) == "position[0] = 1.25 rad outside +-1.0 rad"
    # exactly on the bound is plausible
    assert PlausibilityCheck(limits).reason((-1.0, 2.0), 0, MS) is None


def test_a_too_fast_move_names_the_joint_that_moved_too_fast() -> None:
    check = PlausibilityCheck(MeasurementLimits(max_speed=(100.0, 50.0)))
    check.accept((0.0, 0.0), 0)
    # 2 ms since the last accepted stamp: alpha may move 0.2 rad, beta 0.1 rad
    assert check.reason((0.2, -0.1), 2 * MS, MS) is None
    assert (
        check.reason((0.0, -0.125), 2 * MS, MS)
        == "position[1] moved -0.125 rad in 0.002 s, faster than 50.0 rad/s"
    )
    assert (
        check.reason((0.25, 0.0), 2 * MS, MS)
        == "position[0] moved +0.25 rad in 0.002 s, faster than 100.0 rad/s"
    )
    # a stamp before the last accepted one: the allowance is from the distance between the stamps
    assert check.reason((0.0, -0.05), -MS, MS) is None
    assert check.reason((0.0, -0.1), -MS, MS) is not None
    assert check.reason((0.0, -0.1), -2 * MS, MS) is None


def test_admit_accepts_only_plausible_positions() -> None:
    check = PlausibilityCheck(MeasurementLimits(max_speed=(100.0, 100.0)))
    assert check.admit((0.0, 0.0), 0, MS) is None
    assert check.admit((0.05, 0.0), MS, MS) is None  # accepted: the next move is measured from 0.05
    assert check.admit((0.15, 0.0), 2 * MS, MS) is None
    assert check.admit((1.0, 0.0), 3 * MS, MS) is not None  # refused: not the new reference
    assert check.admit((0.2, -0.1), 4 * MS, MS) is None  # moved (0.05, -0.1) rad in 2 ms since 0.15


def test_reconfigured_limits_apply_to_the_next_check_and_must_be_limits() -> None:
    check = PlausibilityCheck()
    assert check.reason((1.45, 0.0), 0, MS) is None
    check.reconfigure(MeasurementLimits(position_limit=(1.4, 1.4)))
    assert check.reason((1.45, 0.0), 0, MS) == "position[0] = 1.45 rad outside +-1.4 rad"
    with pytest.raises(TypeError, match=r"^limits must be a MeasurementLimits"):
        check.reconfigure(OutputLimitConfig())  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("config", "field", "value"),
    [
        (MeasurementLimits, "position_limit", (0.0, 1.0)),
        (MeasurementLimits, "max_speed", (1.0, -1.0)),
        (OutputLimitConfig, "torque_limit", (0.0, 1.0)),
        (OutputLimitConfig, "rate_limit", (1.0, -1.0)),
    ],
)
def test_limits_must_be_positive(config: type, field: str, value: tuple[float, float]) -> None:
    with pytest.raises(ValueError, match=f"^{field}"):
        config(**{field: value})


def test_output_limits_may_be_infinite() -> None:
    config = OutputLimitConfig(torque_limit=(math.inf, math.inf), rate_limit=(math.inf, 1.0))  # no limit
    assert config.torque_limit == (math.inf, math.inf)


def test_the_limiter_is_quiet_before_its_first_step_and_after_reset() -> None:
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(1.0, 1.0), rate_limit=(1.0, 1.0)))
    for key in ("tau_unlimited", "tau", "clamped", "clamps"):
        np.testing.assert_array_equal(limiter.internals[key], [0.0, 0.0])
    assert limiter.limit_floats((5.0, 0.5), 1e-3) == (1.0, 0.5)
    assert limiter.clamps == 1
    limiter.reset()
    assert limiter.clamps == 0
    for key in ("tau_unlimited", "tau", "clamped", "clamps"):
        np.testing.assert_array_equal(limiter.internals[key], [0.0, 0.0])
    assert limiter.limit_floats((-0.5, 0.5), 1e-3) == (-0.5, 0.5)  # no rate limit from before the reset


def test_a_clamp_of_either_joint_counts_once_per_step() -> None:
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(10.0, 20.0)))
    limiter.limit_floats((0.0, 25.0), 1e-3)
    np.testing.assert_array_equal(limiter.internals["clamped"], [0.0, 1.0])
    limiter.limit_floats((-11.0, 0.0), 1e-3)
    np.testing.assert_array_equal(limiter.internals["clamped"], [1.0, 0.0])
    limiter.limit_floats((-11.0, 30.0), 1e-3)
    limiter.limit_floats((10.0, -20.0), 1e-3)  # exactly at the limits: not clamped
    assert limiter.clamps == 3
    np.testing.assert_array_equal(limiter.internals["clamps"], [3.0, 3.0])
    np.testing.assert_array_equal(limiter.internals["clamped"], [0.0, 0.0])


def test_the_rate_limit_bounds_both_directions_of_each_joint() -> None:
    limiter = OutputLimiter(OutputLimitConfig(rate_limit=(1000.0, 2000.0)))
    limiter.limit_floats((10.0, -10.0), 1e-3)
    # alpha may change by 1 N m, beta by 2 N m in 1 ms; 2 ms allows twice that
    assert limiter.limit_floats((0.0, 0.0), 1e-3) == (9.0, -8.0)
    assert limiter.limit_floats((20.0, -20.0), 2e-3) == (11.0, -12.0)
    np.testing.assert_array_equal(limiter.internals["tau_unlimited"], [20.0, -20.0])
    np.testing.assert_array_equal(limiter.internals["tau"], [11.0, -12.0])
    np.testing.assert_array_equal(limiter.internals["clamped"], [1.0, 1.0])


def test_the_rate_limit_applies_before_the_torque_limit() -> None:
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(5.0, 5.0), rate_limit=(1000.0, 1000.0)))
    assert limiter.limit_floats((100.0, -100.0), 1e-3) == (5.0, -5.0)  # first step: no rate limit
    # from 5: the rate limit allows 4..6, the torque limit then 5
    assert limiter.limit_floats((100.0, -100.0), 1e-3) == (5.0, -5.0)


def test_reconfigure_keeps_the_previous_output_and_the_count() -> None:
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(10.0, 10.0)))
    limiter.limit_floats((50.0, 0.0), 1e-3)
    limiter.reconfigure(OutputLimitConfig(rate_limit=(1000.0, 1000.0)))
    assert limiter.limit_floats((50.0, 0.0), 1e-3) == (11.0, 0.0)
    assert limiter.clamps == 2
    with pytest.raises(TypeError, match=r"^config must be a OutputLimitConfig"):
        limiter.reconfigure(MeasurementLimits())  # type: ignore[arg-type]


def test_a_nan_output_is_not_counted_as_a_clamp_and_inf_passes_through() -> None:
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(1.0, 1.0)))
    tau = limiter.limit_floats((math.nan, -math.inf), 1e-3)
    assert math.isnan(tau[0]) and tau[1] == -math.inf
    np.testing.assert_array_equal(limiter.internals["clamped"], [0.0, 0.0])
    assert limiter.clamps == 0


class _Recorder:
    """A law that tracks saturation and records the calls."""

    def __init__(self) -> None:
        self.calls: list[tuple[tuple[float, float], tuple[float, float], float]] = []

    def track_saturation(
        self, unlimited: tuple[float, float], limited: tuple[float, float], dt: float
    ) -> None:
        self.calls.append((unlimited, limited, dt))


def test_track_saturation_tells_only_a_tracking_law_and_only_finite_limited_outputs() -> None:
    law = _Recorder()
    track_saturation(law, (1.0, 2.0), (1.0, 2.0), 1e-3)
    assert law.calls == []  # not limited
    for bad in (math.inf, -math.inf, math.nan):
        track_saturation(law, (bad, 2.0), (1.0, 1.0), 1e-3)
        track_saturation(law, (1.0, bad), (1.0, 1.0), 1e-3)
        track_saturation(law, (5.0, 2.0), (bad, 2.0), 1e-3)
        track_saturation(law, (5.0, 2.0), (1.0, bad), 1e-3)
    assert law.calls == []
    track_saturation(law, (5.0, 2.0), (1.0, 2.0), 2e-3)
    assert law.calls == [((5.0, 2.0), (1.0, 2.0), 2e-3)]
    track_saturation(object(), (5.0, 2.0), (1.0, 2.0), 2e-3)  # a law without it: nothing to tell


def test_the_refusal_names_the_joint_out_of_range_when_the_other_is_exactly_on_its_bound() -> None:
    limits = MeasurementLimits(position_limit=(1.0, 2.0))
    assert PlausibilityCheck(limits).reason((1.0, 2.5), 0, MS) == "position[1] = 2.5 rad outside +-2.0 rad"
    assert PlausibilityCheck(limits).reason((-1.5, 2.0), 0, MS) == "position[0] = -1.5 rad outside +-1.0 rad"


def test_the_too_fast_joint_is_judged_against_its_own_speed() -> None:
    check = PlausibilityCheck(MeasurementLimits(max_speed=(100.0, 50.0)))
    check.accept((0.0, 0.0), 0)
    # alpha at (0.2) or below (0.15) its own allowance of 0.2 rad, beta 0.125 > 0.1 rad: beta is named
    for alpha in (0.2, 0.15):
        assert (check.reason((alpha, -0.125), 2 * MS, MS) or "").startswith("position[1] moved -0.125 rad")


def test_the_move_is_measured_from_the_last_accepted_position_and_stamp() -> None:
    check = PlausibilityCheck(MeasurementLimits(max_speed=(100.0, 100.0)))
    check.accept((0.3, -0.2), 10 * MS)
    # 1 ms later: up to 0.1 rad per joint from (0.3, -0.2)
    assert check.reason((0.35, -0.25), 11 * MS, MS) is None
    assert check.reason((0.39, -0.11), 11 * MS, MS) is None
    assert (
        check.reason((0.45, -0.2), 11 * MS, MS)
        == "position[0] moved +0.15 rad in 0.001 s, faster than 100.0 rad/s"
    )
    assert (
        check.reason((0.3, -0.35), 11 * MS, MS)
        == "position[1] moved -0.15 rad in 0.001 s, faster than 100.0 rad/s"
    )


def test_a_clamped_joint_counts_even_when_the_other_is_nan() -> None:
    limiter = OutputLimiter(OutputLimitConfig(torque_limit=(10.0, 10.0)))
    limiter.limit_floats((50.0, math.nan), 1e-3)
    np.testing.assert_array_equal(limiter.internals["clamped"], [1.0, 0.0])
    assert limiter.clamps == 1
    limiter.limit_floats((math.nan, -50.0), 1e-3)
    np.testing.assert_array_equal(limiter.internals["clamped"], [0.0, 1.0])
