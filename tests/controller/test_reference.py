"""Reference generators: shapes, analytic derivatives, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_controller.reference import RampHoldReference, SineReference, StepReference, make_reference


def finite_difference_check(reference: SineReference | RampHoldReference, times: np.ndarray) -> None:
    h = 1e-6
    plus, minus, centre = reference.sample(times + h), reference.sample(times - h), reference.sample(times)
    assert_allclose((plus[:, 0] - minus[:, 0]) / (2 * h), centre[:, 1], atol=1e-6)
    assert_allclose((plus[:, 1] - minus[:, 1]) / (2 * h), centre[:, 2], atol=1e-5)


def test_sine_is_eq_41_with_analytic_derivatives() -> None:
    reference = SineReference()
    t = 0.3
    assert_allclose(reference.evaluate(t)[0], [math.sin(math.pi * t), 0.785 * math.sin(math.pi * t)])
    finite_difference_check(reference, np.linspace(0.0, 5.0, 37))


@pytest.mark.parametrize("profile", ["linear", "quintic"])
def test_ramp_hold(profile: str) -> None:
    reference = RampHoldReference(
        target=(0.5, -0.2), ramp_time=0.4, start_time=0.1, initial=(0.1, 0.0), profile=profile
    )
    assert_allclose(reference(0.0)[0], [0.1, 0.0])
    assert_allclose(reference(0.3)[0], [0.3, -0.1], atol=1e-12)
    assert_allclose(reference(1.0), [[0.5, -0.2], [0.0, 0.0], [0.0, 0.0]], atol=1e-12)
    inside = np.linspace(0.12, 0.48, 13)
    finite_difference_check(reference, inside)


def test_quintic_ramp_starts_and_ends_at_rest() -> None:
    reference = RampHoldReference(ramp_time=0.5)
    assert_allclose(reference(0.0)[1:], 0.0, atol=1e-12)
    assert_allclose(reference(0.5)[1:], 0.0, atol=1e-12)


def test_step() -> None:
    reference = StepReference(start_time=0.2)
    assert_allclose(reference(0.1), np.zeros((3, 2)))
    assert_allclose(reference(0.2), [[1.0, 0.785], [0.0, 0.0], [0.0, 0.0]])


GENERATORS = (
    StepReference(start_time=0.3),
    SineReference(amplitude=(0.4, -1.2), angular_frequency=7.0, phase=(0.3, -2.0)),
    RampHoldReference(profile="linear", start_time=0.2, ramp_time=0.7),
    RampHoldReference(initial=(0.5, -0.5), start_time=0.1, ramp_time=1.3),
)


@settings(max_examples=50, deadline=None)
@given(times=st.lists(st.floats(0.0, 10.0, allow_nan=False, allow_subnormal=True), min_size=1, max_size=20))
@pytest.mark.parametrize("reference", GENERATORS)
def test_sample_evaluate_and_rows_agree_bit_for_bit(
    reference: StepReference | SineReference | RampHoldReference, times: list[float]
) -> None:
    """The offline loop samples a whole run, the nodes one stamp at a time: the same values exactly."""
    samples = reference.sample(np.array(times))
    assert samples.shape == (len(times), 3, 2)
    for k, t in enumerate(times):
        np.testing.assert_array_equal(samples[k], reference.evaluate(t))
        np.testing.assert_array_equal(samples[k], np.array(reference.rows(t)))


def test_make_reference() -> None:
    reference = make_reference("sine", amplitude=[0.5, 0.5], angular_frequency=2.0)
    assert reference == SineReference(amplitude=(0.5, 0.5), angular_frequency=2.0)
    assert make_reference("step") == StepReference()
    assert isinstance(make_reference("ramp_hold", target=(0.2, 0.1)), RampHoldReference)


@pytest.mark.parametrize(
    ("kind", "params", "message"),
    [
        ("square", {}, "kind must be one of"),
        ("sine", {"frequency": 1.0}, "invalid parameters"),
        ("sine", {"angular_frequency": 0.0}, "angular_frequency"),
        ("sine", {"amplitude": (1.0, math.nan)}, "amplitude"),
        ("sine", {"amplitude": (1.0, 2.0, 3.0)}, "amplitude"),
        ("step", {"start_time": -1.0}, "start_time"),
        ("step", {"amplitude": (math.inf, 0.0)}, "amplitude"),
        ("ramp_hold", {"ramp_time": 0.0}, "ramp_time"),
        ("ramp_hold", {"profile": "cubic"}, "profile"),
        ("ramp_hold", {"initial": (0.0,)}, "initial"),
    ],
)
def test_rejections(kind: str, params: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make_reference(kind, **params)


@pytest.mark.parametrize("t", [math.nan, math.inf])
def test_time_must_be_finite(t: float) -> None:
    with pytest.raises(ValueError, match="t must"):
        SineReference().evaluate(t)
    with pytest.raises(ValueError, match="times must"):
        SineReference().sample(np.array([0.0, t]))
