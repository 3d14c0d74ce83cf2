"""Tracking differentiator (eq. 24-25) against Han's fhan."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_controller.td import TrackingDifferentiator, TrackingDifferentiatorConfig, fhan, fst

errors = st.floats(-2.0, 2.0, allow_subnormal=True)
rates = st.floats(-50.0, 50.0, allow_subnormal=True)
speeds = st.floats(1.0, 1e6, allow_subnormal=False)
steps = st.floats(1e-4, 1e-2, allow_subnormal=False)


@settings(deadline=None, max_examples=300)
@given(e=errors, x2=rates, sigma=speeds, h=steps)
def test_fst_equals_fhan_when_h_equals_t(e: float, x2: float, sigma: float, h: float) -> None:
    assert fst(e, x2, sigma, h, h) == pytest.approx(fhan(e, x2, sigma, h), rel=1e-12, abs=1e-9)


def test_fst_differs_from_fhan_when_h_differs_from_t() -> None:
    # Linear zone: fst = -(x2 + (e + t x2)/h)/h, fhan = -(x2 + (e + h x2)/h)/h.
    e, x2, sigma, h, t = 0.001, 0.5, 1e5, 0.004, 0.001
    assert fst(e, x2, sigma, h, t) == pytest.approx(-(x2 + (e + t * x2) / h) / h, rel=1e-12)
    assert fhan(e, x2, sigma, h) == pytest.approx(-(x2 + (e + h * x2) / h) / h, rel=1e-12)
    assert abs(fst(e, x2, sigma, h, t) - fhan(e, x2, sigma, h)) > 1.0


@settings(deadline=None)
@given(e=errors, x2=rates, sigma=speeds, h=steps)
def test_fhan_is_odd_and_bounded(e: float, x2: float, sigma: float, h: float) -> None:
    value = fhan(e, x2, sigma, h)
    assert fhan(-e, -x2, sigma, h) == pytest.approx(-value, rel=1e-12, abs=1e-9)
    assert abs(value) <= sigma * (1 + 1e-12)


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_fst_is_continuous_at_the_zone_boundary(side: float) -> None:
    """The corrected nonlinear branch meets the linear one at |y| = delta1 for both signs of y."""
    sigma, h, t = 100.0, 0.05, 0.05
    boundary = h * h * sigma
    below = fst(side * boundary * (1 - 1e-9), 0.0, sigma, h, t)
    above = fst(side * boundary * (1 + 1e-9), 0.0, sigma, h, t)
    assert below == pytest.approx(above, rel=1e-6)


def test_step_is_eq_24_with_fhan_when_h_equals_dt() -> None:
    dt = 0.002
    td = TrackingDifferentiator(TrackingDifferentiatorConfig(speed=(500.0, 2000.0), filter_factor=(dt, dt)))
    rng = np.random.default_rng(1)
    x1 = np.array([0.1, -0.2])
    x2 = np.zeros(2)
    td.step(x1, dt)
    for _ in range(200):
        v = x1 + rng.normal(0.0, 0.05, 2)
        accel = [fhan(x1[j] - v[j], x2[j], (500.0, 2000.0)[j], dt) for j in range(2)]
        x1, x2 = x1 + dt * x2, x2 + dt * np.array(accel)
        got_x1, got_x2 = td.step(v, dt)
        assert_allclose(got_x1, x1, rtol=1e-12, atol=1e-12)
        assert_allclose(got_x2, x2, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        # Linear zone: delta = h sigma = 400, delta1 = 1.6, y = e + t x2 = 0.0015, g = x2 + y/h = 0.875.
        ((0.001, 0.5, 1e5, 0.004, 0.001), -1e5 * 0.875 / 400.0),
        # Nonlinear, unsaturated: delta = 5, delta1 = 0.25, y = 0.83 - 0.08 = 0.75,
        # g = -8 + (sqrt(8 * 100 * 0.75 + 25) - 5) / 2 = -8 + 10 = 2, fst = -100 * 2 / 5.
        ((0.83, -8.0, 100.0, 0.05, 0.01), -40.0),
        # Nonlinear, saturated: y = -0.77 + 0.02 = -0.75, g = 2 - 10 = -8 <= -delta, fst = +sigma.
        ((-0.77, 2.0, 100.0, 0.05, 0.01), 100.0),
    ],
)
def test_fst_at_hand_computed_points_with_h_different_from_t(
    args: tuple[float, float, float, float, float], expected: float
) -> None:
    """Eq. 25 off the default h = t: y uses the step t; delta, delta1 and y/h use the filter factor h.

    args: (e, x2, sigma, h, t).
    """
    assert fst(*args) == pytest.approx(expected, rel=1e-12)


def test_step_with_filter_factor_above_dt_at_hand_computed_states() -> None:
    """Eq. 24-25 with h != t (0.05 and 0.02 s at dt = 0.01 s), sigma = 100, three steps by hand.

    alpha (nonlinear zone): step 2: e = 0.83 - 0.08 = 0.75 = y, g = (sqrt(625) - 5)/2 = 10 >= delta = 5, so
    fst = -100: x2 = -1. Step 3: y = 0.75 - 0.01 = 0.74, g = -1 + (sqrt(617) - 5)/2 = 8.92 >= 5: x1 = 0.82,
    x2 = -2. beta (linear zone, delta = 2, delta1 = 0.04): step 2: y = e = 0.03, g = 0.03/0.02 = 1.5,
    fst = -100 * 1.5/2 = -75: x2 = -0.75. Step 3: y = 0.03 + 0.01 (-0.75) = 0.0225, g = -0.75 + 1.125 = 0.375,
    fst = -18.75: x1 = -0.0075, x2 = -0.9375.
    """
    td = TrackingDifferentiator(
        TrackingDifferentiatorConfig(speed=(100.0, 100.0), filter_factor=(0.05, 0.02))
    )
    x1, x2 = td.step([0.83, 0.0], 0.01)
    assert list(x1) == [0.83, 0.0] and list(x2) == [0.0, 0.0]
    x1, x2 = td.step([0.08, -0.03], 0.01)
    assert_allclose(x1, [0.83, 0.0], rtol=1e-12, atol=1e-15)
    assert_allclose(x2, [-1.0, -0.75], rtol=1e-12)
    x1, x2 = td.step([0.08, -0.03], 0.01)
    assert_allclose(x1, [0.82, -0.0075], rtol=1e-12)
    assert_allclose(x2, [-2.0, -0.9375], rtol=1e-12)


def test_first_step_starts_at_the_sample_at_rest() -> None:
    td = TrackingDifferentiator()
    x1, x2 = td.step([0.3, -0.4], 0.001)
    assert_allclose(x1, [0.3, -0.4])
    assert_allclose(x2, [0.0, 0.0])


def test_tracks_a_ramp_and_its_slope() -> None:
    dt = 0.001
    td = TrackingDifferentiator()
    slope = np.array([0.5, -1.0])
    for k in range(2000):
        x1, x2 = td.step(slope * k * dt, dt)
    assert_allclose(x2, slope, rtol=1e-6)
    # Linear-zone lag of the filter: position behind the input by about (h + dt) times the slope.
    assert np.all(np.abs(x1 - slope * 1999 * dt) < 0.01)


def test_filter_factor_below_dt_is_rejected_at_step() -> None:
    td = TrackingDifferentiator(TrackingDifferentiatorConfig(filter_factor=(0.002, 0.0005)))
    td.step([0.0, 0.0], 0.0005)
    with pytest.raises(ValueError, match="filter_factor"):
        td.step([0.0, 0.0], 0.001)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("speed", (0.0, 1.0)),
        ("speed", (-1.0, 1.0)),
        ("speed", (math.nan, 1.0)),
        ("speed", (math.inf, 1.0)),
        ("speed", (1.0,)),
        ("filter_factor", (0.001, 0.0)),
        ("filter_factor", [0.001, 0.001]),
        ("filter_factor", (0.001, True)),
    ],
)
def test_config_rejections(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        TrackingDifferentiatorConfig(**{field: value})  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", [[0.0], [[0.0, 0.0]], [math.nan, 0.0]])
def test_step_rejects_bad_input(bad: object) -> None:
    with pytest.raises(ValueError, match="v"):
        TrackingDifferentiator().step(bad, 0.001)  # type: ignore[arg-type]


@pytest.mark.parametrize("dt", [0.0, -0.001, math.nan, math.inf])
def test_step_rejects_bad_dt(dt: float) -> None:
    with pytest.raises(ValueError, match="dt"):
        TrackingDifferentiator().step([0.0, 0.0], dt)


@settings(deadline=None, max_examples=100)
@given(samples=st.lists(st.tuples(errors, errors), min_size=1, max_size=10))
def test_next_position_is_the_x1_of_the_next_step(samples: list[tuple[float, float]]) -> None:
    """Known a step ahead (it needs no measurement), bit for bit; None before the first step."""
    td = TrackingDifferentiator()
    assert td.next_position(1e-3) is None
    for v0, v1 in samples:
        td.step_floats(v0, v1, 1e-3)
        predicted = td.next_position(1e-3)
        assert predicted == td.step_floats(-v1, v0, 1e-3)[:2]
