"""Metrics of SPEC section 5 against analytic references, and rejection of malformed inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_analysis.errors import MetricsInputError
from smm_analysis.metrics import (
    control_energy,
    end_effector_errors,
    joint_indices,
    max_abs_error,
    mean_abs_error,
    rms_error,
    step_metrics,
    torque_increment_rms,
    validated_time,
)

from smm_dynamics import SMMParameters, end_effector_position

PERIOD_NS = 100_000  # 0.1 ms: fine enough that interpolation errors stay far below the tolerances


def _time(duration: float, period_ns: int = PERIOD_NS) -> np.ndarray:
    return np.arange(0, round(duration * 1e9) + 1, period_ns, dtype=np.int64)


@given(
    amplitude=st.floats(0.01, 5.0, allow_subnormal=False),
    periods=st.integers(1, 5),
    frequency=st.floats(0.5, 5.0, allow_subnormal=False),
)
@settings(max_examples=25, deadline=None)
def test_rms_of_sine_over_whole_periods_is_amplitude_over_sqrt2(
    amplitude: float, periods: int, frequency: float
) -> None:
    samples = 2000 * periods
    duration = periods / frequency
    t_ns = np.round(np.linspace(0.0, duration, samples + 1) * 1e9).astype(np.int64)
    error = amplitude * np.sin(2.0 * np.pi * frequency * t_ns / 1e9)
    assert_allclose(rms_error(t_ns, error), amplitude / math.sqrt(2.0), rtol=1e-6)


def test_rms_of_constant_and_ramp() -> None:
    t_ns = _time(2.0)
    assert_allclose(rms_error(t_ns, np.full(t_ns.size, -0.3)), 0.3, rtol=1e-12)
    ramp = t_ns / 1e9  # e = t on [0, 2]: (1/2) int t^2 dt = 4/3
    assert_allclose(rms_error(t_ns, ramp), math.sqrt(4.0 / 3.0), rtol=1e-6)


def test_rms_uses_actual_sample_intervals() -> None:
    # Non-uniform sampling of e = t on [0, 1]: the trapezoid of t^2 must still approximate 1/3.
    t_s = np.sort(np.concatenate(([0.0, 1.0], np.random.default_rng(3).uniform(0.0, 1.0, 20000))))
    t_ns = np.unique(np.round(t_s * 1e9).astype(np.int64))
    assert_allclose(rms_error(t_ns, t_ns / 1e9), math.sqrt(1.0 / 3.0), rtol=1e-4)


def test_control_energy_of_sine_and_constant() -> None:
    t_ns = _time(2.0)
    torque = 3.0 * np.sin(np.pi * t_ns / 1e9)  # 2 s = one period: int 9 sin^2 = 9
    assert_allclose(control_energy(t_ns, torque), 9.0, rtol=1e-6)
    assert_allclose(control_energy(t_ns, np.full(t_ns.size, 2.0)), 8.0, rtol=1e-12)


def test_max_and_mean_abs_error() -> None:
    error = np.array([0.1, -0.4, 0.2, -0.1])
    assert max_abs_error(error) == pytest.approx(0.4)
    assert mean_abs_error(error) == pytest.approx(0.2)


def test_joint_indices_per_joint() -> None:
    t_ns = _time(2.0)
    t = t_ns / 1e9
    reference = np.column_stack((np.sin(np.pi * t), 0.5 * np.sin(np.pi * t)))
    error = np.column_stack((0.02 * np.sin(np.pi * t), np.full(t.size, -0.01)))
    torque = np.column_stack((np.ones(t.size), 2.0 * np.ones(t.size)))
    indices = joint_indices(t_ns, reference, reference - error, torque)
    assert_allclose(indices["alpha"].RMS, 0.02 / math.sqrt(2.0), rtol=1e-6)
    assert_allclose(indices["alpha"].Ma, 0.02, rtol=1e-6)
    assert_allclose(indices["alpha"].Ave, 0.02 * 2.0 / math.pi, rtol=1e-3)
    assert_allclose(indices["beta"].RMS, 0.01, rtol=1e-12)
    assert_allclose(indices["beta"].eps_u, 8.0, rtol=1e-12)
    assert_allclose(indices["alpha"].eps_u, 2.0, rtol=1e-12)


@pytest.mark.parametrize("tau", [0.01, 0.03, 0.1])
@pytest.mark.parametrize("amplitude", [1.0, -0.785])
def test_first_order_step_response(tau: float, amplitude: float) -> None:
    t_ns = _time(1.0, period_ns=10_000)
    response = amplitude * (1.0 - np.exp(-(t_ns / 1e9) / tau))
    metrics = step_metrics(t_ns, response, amplitude)
    assert_allclose(metrics.rise_time, math.log(9.0) * tau, rtol=1e-3)  # 2.197 tau
    assert_allclose(metrics.settling_time, math.log(50.0) * tau, rtol=1e-3)  # 3.912 tau
    assert metrics.overshoot == 0.0
    assert metrics.overshoot_fraction == 0.0


@pytest.mark.parametrize("zeta", [0.2, 0.5, 0.7])
def test_second_order_underdamped_overshoot(zeta: float) -> None:
    omega_n = 40.0
    omega_d = omega_n * math.sqrt(1.0 - zeta**2)
    t_ns = _time(2.0, period_ns=10_000)
    t = t_ns / 1e9
    phase = math.acos(zeta)
    unit = 1.0 - np.exp(-zeta * omega_n * t) * np.sin(omega_d * t + phase) / math.sqrt(1.0 - zeta**2)
    amplitude = 0.785
    metrics = step_metrics(t_ns, amplitude * unit, amplitude)
    expected_fraction = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta**2))
    assert_allclose(metrics.overshoot_fraction, expected_fraction, rtol=1e-4)
    assert_allclose(metrics.overshoot, amplitude * expected_fraction, rtol=1e-4)
    # The envelope bound of the 2 % settling time: the true settling time never exceeds it.
    envelope = -math.log(0.02 * math.sqrt(1.0 - zeta**2)) / (zeta * omega_n)
    assert 0.0 < metrics.settling_time <= envelope


def test_step_metrics_with_offset_initial_value_and_step_time() -> None:
    t_ns = _time(1.0, period_ns=10_000)
    t = t_ns / 1e9
    step_at = 0.2
    tau = 0.05
    response = np.where(t < step_at, 0.5, 0.5 + 1.5 * (1.0 - np.exp(-(t - step_at) / tau)))
    metrics = step_metrics(t_ns, response, 2.0, initial=0.5, step_time_ns=200_000_000)
    assert_allclose(metrics.rise_time, math.log(9.0) * tau, rtol=1e-3)
    assert_allclose(metrics.settling_time, math.log(50.0) * tau, rtol=1e-3)


def test_step_that_never_arrives_has_infinite_times() -> None:
    t_ns = _time(0.5)
    metrics = step_metrics(t_ns, 0.5 * (1.0 - np.exp(-(t_ns / 1e9) / 0.01)), 1.0)
    assert math.isinf(metrics.rise_time)
    assert math.isinf(metrics.settling_time)


def test_end_effector_errors_zero_when_on_reference_and_match_direct_kinematics() -> None:
    params = SMMParameters()
    t_ns = _time(1.0, period_ns=1_000_000)
    t = t_ns / 1e9
    reference = np.column_stack((np.sin(np.pi * t), 0.785 * np.sin(np.pi * t)))
    zero = end_effector_errors(t_ns, reference, reference, params)
    assert all(zero[axis].max_mm == 0.0 and zero[axis].rms_mm == 0.0 for axis in ("x", "y", "z"))
    offset = reference + np.array([0.0, 0.01])
    errors = end_effector_errors(t_ns, reference, offset, params)
    expected = np.array(
        [
            (np.asarray(end_effector_position(a, params)) - np.asarray(end_effector_position(b, params)))
            * 1e3
            for a, b in zip(reference, offset, strict=True)
        ]
    )
    for index, axis in enumerate(("x", "y", "z")):
        assert_allclose(errors[axis].max_mm, np.max(np.abs(expected[:, index])), rtol=1e-12)
        assert_allclose(errors[axis].rms_mm, rms_error(t_ns, expected[:, index]), rtol=1e-12)
    assert errors["z"].max_mm > 0.0


def test_rejects_mismatched_lengths() -> None:
    t_ns = _time(0.1)
    with pytest.raises(MetricsInputError, match="samples"):
        rms_error(t_ns, np.zeros(t_ns.size - 1))
    with pytest.raises(MetricsInputError, match="samples"):
        control_energy(t_ns, np.zeros(t_ns.size + 1))
    with pytest.raises(MetricsInputError, match="samples"):
        joint_indices(t_ns, np.zeros((t_ns.size, 2)), np.zeros((t_ns.size - 1, 2)), np.zeros((t_ns.size, 2)))
    with pytest.raises(MetricsInputError, match="samples"):
        step_metrics(t_ns, np.zeros(3), 1.0)


@pytest.mark.parametrize(
    "stamps",
    [
        np.array([0, 2, 1, 3], dtype=np.int64),
        np.array([0, 1, 1, 2], dtype=np.int64),
    ],
)
def test_rejects_non_increasing_time(stamps: np.ndarray) -> None:
    with pytest.raises(MetricsInputError, match="strictly increasing"):
        rms_error(stamps, np.zeros(stamps.size))
    with pytest.raises(MetricsInputError, match="strictly increasing"):
        step_metrics(stamps, np.linspace(0.0, 1.0, stamps.size), 1.0)


def test_rejects_float_or_short_time() -> None:
    with pytest.raises(MetricsInputError, match="integer"):
        rms_error(np.array([0.0, 0.1, 0.2]), np.zeros(3))
    with pytest.raises(MetricsInputError, match="at least 2"):
        rms_error(np.array([0], dtype=np.int64), np.zeros(1))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_rejects_non_finite_values(bad: float) -> None:
    t_ns = _time(0.01)
    values = np.zeros(t_ns.size)
    values[3] = bad
    with pytest.raises(MetricsInputError, match="NaN"):
        rms_error(t_ns, values)
    with pytest.raises(MetricsInputError, match="NaN"):
        max_abs_error(values)
    with pytest.raises(MetricsInputError, match="NaN"):
        mean_abs_error(values)
    with pytest.raises(MetricsInputError, match="NaN"):
        step_metrics(t_ns, values, 1.0)
    joint = np.zeros((t_ns.size, 2))
    joint[2, 1] = bad
    with pytest.raises(MetricsInputError, match="NaN"):
        joint_indices(t_ns, joint, np.zeros_like(joint), np.zeros_like(joint))


def test_rejects_zero_step_and_bad_band() -> None:
    t_ns = _time(0.01)
    with pytest.raises(MetricsInputError, match="differ"):
        step_metrics(t_ns, np.ones(t_ns.size), 1.0, initial=1.0)
    with pytest.raises(MetricsInputError, match="settling_band"):
        step_metrics(t_ns, np.ones(t_ns.size), 1.0, settling_band=0.0)


def test_metrics_errors_are_value_errors() -> None:
    with pytest.raises(ValueError):
        rms_error(np.array([0, 1], dtype=np.int64), np.zeros((2, 2)))


def test_torque_increment_rms_of_a_ramp_an_alternation_and_a_constant() -> None:
    assert torque_increment_rms(np.arange(11) * 0.25) == pytest.approx(0.25, rel=1e-12)
    assert torque_increment_rms([1.0, -1.0, 1.0, -1.0, 1.0]) == pytest.approx(2.0, rel=1e-12)  # chatter
    assert torque_increment_rms(np.full(7, 3.0)) == 0.0


def test_torque_increment_rms_of_white_noise_is_sqrt2_times_its_std() -> None:
    noise = np.random.default_rng(3).normal(0.0, 0.5, 200_000)
    assert torque_increment_rms(noise) == pytest.approx(math.sqrt(2.0) * 0.5, rel=0.01)


@pytest.mark.parametrize("torque", [[1.0], [0.0, math.nan], np.zeros((3, 2))])
def test_torque_increment_rms_rejects_bad_input(torque: object) -> None:
    with pytest.raises(MetricsInputError):
        torque_increment_rms(torque)  # type: ignore[arg-type]


def test_joint_indices_carry_the_torque_increment() -> None:
    t_ns = _time(0.01)
    torque = np.stack([np.arange(t_ns.size) * 0.1, np.zeros(t_ns.size)], axis=1)
    indices = joint_indices(t_ns, np.zeros((t_ns.size, 2)), np.zeros((t_ns.size, 2)), torque)
    assert indices["alpha"].du_rms == pytest.approx(0.1, rel=1e-12)
    assert indices["beta"].du_rms == 0.0


def test_energy_above_a_cutoff_splits_a_two_tone_torque_by_parseval() -> None:
    from smm_analysis.reproduction.energy_study import energy_above

    t_ns = np.arange(1000, dtype=np.int64) * 1_000_000  # 1 s at 1 kHz, whole periods of both tones
    t = t_ns / 1e9
    torque = 2.0 * np.sin(2 * np.pi * 5 * t) + 0.5 * np.sin(2 * np.pi * 100 * t)
    assert energy_above(t_ns, torque, 20.0) == pytest.approx(0.5**2 / 2, rel=1e-9)
    assert energy_above(t_ns, torque, 1.0) == pytest.approx(2.0**2 / 2 + 0.5**2 / 2, rel=1e-9)


S = 1_000_000_000  # ns per s


def test_step_metrics_at_hand_computed_interpolations() -> None:
    """Piecewise-linear samples at 1 s: every crossing is interpolated between two samples.

    10 %: between 0.05 (1 s) and 0.5 (2 s) at 1 + 0.05/0.45 = 1 + 1/9 s; 90 %: between 0.5 and 1.2 at
    2 + 0.4/0.7 = 2 + 4/7 s; rise time 1 + 4/7 - 1/9 = 92/63 s. Overshoot 0.2. Last sample outside the 2 %
    band: 0.97 at 4 s (distance 0.03), next 1.0 (distance 0): settling at 4 + (0.03 - 0.02)/0.03 = 4 + 1/3 s.
    """
    t_ns = np.arange(6, dtype=np.int64) * S
    metrics = step_metrics(t_ns, [0.0, 0.05, 0.5, 1.2, 0.97, 1.0], 1.0)
    assert metrics.rise_time == pytest.approx(92.0 / 63.0, rel=1e-12)
    assert metrics.overshoot_fraction == pytest.approx(0.2, rel=1e-12)
    assert metrics.overshoot == pytest.approx(0.2, rel=1e-12)
    assert metrics.settling_time == pytest.approx(4.0 + 1.0 / 3.0, rel=1e-12)


def test_step_metrics_of_a_step_down_reached_at_once() -> None:
    """Step 0 -> -1 after 10 s: normalised [0.5, 0.95, 1, 1] from the step on.

    10 % is reached at the first kept sample (0 s); 90 % between 0.5 and 0.95 at 0.4/0.45 = 8/9 s;
    settling: distance 0.05 at 1 s then 0: at 1 + (0.05 - 0.02)/0.05 = 1.6 s. A sample before the step is
    ignored; the sample at the step time is kept.
    """
    t_ns = np.array([0, 10, 11, 12, 13], dtype=np.int64) * S
    metrics = step_metrics(t_ns, [5.0, -0.5, -0.95, -1.0, -1.0], -1.0, step_time_ns=10 * S)
    assert metrics.rise_time == pytest.approx(8.0 / 9.0, rel=1e-12)
    assert metrics.overshoot_fraction == 0.0
    assert metrics.settling_time == pytest.approx(1.6, rel=1e-12)


def test_step_metrics_already_settled_and_with_two_samples() -> None:
    t_ns = np.array([0, 1, 2], dtype=np.int64) * S
    settled = step_metrics(t_ns, [1.0, 1.01, 0.995], 1.0, initial=0.0)
    assert (settled.rise_time, settled.settling_time) == (0.0, 0.0)
    two = step_metrics(t_ns, [0.0, 0.0, 1.0], 1.0, step_time_ns=1 * S)  # exactly 2 samples kept
    assert two.settling_time == pytest.approx(0.98, rel=1e-12)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: max_abs_error([]), r"^error must not be empty"),
        (lambda: mean_abs_error([[0.0]]), r"^error must be 1-D"),
        (lambda: rms_error([0, 1, 2], [0.0, math.nan, 0.0]), r"^error holds NaN or Inf at index 1"),
        (lambda: control_energy([0, 1, 2], [0.0, 1.0]), r"^torque has 2 samples but the time base has 3"),
        (lambda: torque_increment_rms([1.0]), r"^torque needs at least 2 samples for an increment, got 1"),
        (lambda: torque_increment_rms([[1.0, 2.0]]), r"^torque must be 1-D"),
        (lambda: validated_time([[0, 1]]), r"^t_ns must be 1-D"),
        (lambda: validated_time([0]), r"^t_ns needs at least 2 samples, got 1"),
        (lambda: validated_time([0, 5, 5, 7]), r"^t_ns must be strictly increasing, got 5 then 5 at index 1"),
        (lambda: validated_time([0, 5, 4]), r"^t_ns must be strictly increasing, got 5 then 4 at index 1"),
        (lambda: validated_time([0, 1, 2, 2]), r"^t_ns must be strictly increasing, got 2 then 2 at index 2"),
        (lambda: step_metrics([0, 1], [0.0], 1.0), r"^response has 1 samples"),
        (
            lambda: step_metrics([0, 1], [0.0, 1.0], 1.0, initial=math.nan),
            r"^target and initial must be finite",
        ),
        (
            lambda: step_metrics([0, 1], [0.0, 1.0], 1.0, settling_band=1.0),
            r"^settling_band must be in \(0, 1\)",
        ),
        (
            lambda: step_metrics([0, 1], [0.0, 1.0], 1.0, step_time_ns=1),
            r"^step_time_ns 1 leaves fewer than 2",
        ),
        (
            lambda: joint_indices([0, 1], np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2))),
            r"^reference must have shape \(N, 2\)",
        ),
        (
            lambda: joint_indices([0, 1], np.zeros((2, 2)), np.zeros((3, 2)), np.zeros((2, 2))),
            r"^position has 3 samples but the time base has 2",
        ),
        (
            lambda: joint_indices([0, 1], np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 3))),
            r"^torque must have shape",
        ),
        (
            lambda: end_effector_errors([0, 1], np.zeros((2, 2, 1)), np.zeros((2, 2)), SMMParameters()),
            r"^reference must have shape",
        ),
        (
            lambda: end_effector_errors([0, 1], np.zeros((2, 2)), np.full((2, 2), math.inf), SMMParameters()),
            r"^position holds NaN or Inf",
        ),
    ],
)
def test_errors_name_the_argument(call: object, message: str) -> None:
    with pytest.raises(MetricsInputError, match=message):
        call()  # type: ignore[operator]


def test_time_steps_of_one_nanosecond_and_two_samples_are_accepted() -> None:
    assert list(validated_time([0, 1, 2])) == [0, 1, 2]
    assert list(validated_time([7, 9])) == [7, 9]
    assert torque_increment_rms([1.0, 3.0]) == pytest.approx(2.0, rel=1e-15)


def test_integrals_keep_their_precision_with_wall_clock_stamps() -> None:
    """Epoch stamps (1.7e18 ns) give the same RMS and energy as stamps from 0: times are relative."""
    k = np.arange(2001, dtype=np.int64)
    error = np.linspace(-0.2, 0.3, k.size)
    torque = np.cos(np.linspace(0.0, 6.0, k.size))
    epoch = 1_700_000_000 * S
    assert rms_error(epoch + k * 1_000_000, error) == pytest.approx(
        rms_error(k * 1_000_000, error), rel=1e-12
    )
    assert control_energy(epoch + k * 1_000_000, torque) == pytest.approx(
        control_energy(k * 1_000_000, torque), rel=1e-12
    )


def test_step_metrics_edge_cases() -> None:
    t_ns = np.array([0, 1, 2], dtype=np.int64) * S
    never = step_metrics(t_ns, [0.0, 0.05, 0.02], 1.0)  # reaches neither 10 % nor 90 %
    assert never.rise_time == math.inf and never.settling_time == math.inf
    # The last sample exactly on the band edge (distance 0.25 = band) is inside: settled when it arrives.
    last = step_metrics(t_ns, [0.0, 0.5, 0.9], 1.0)  # 90 % reached exactly, at the last sample
    assert last.rise_time == pytest.approx(2.0 - 0.1 / 0.5, rel=1e-12)
    edge = step_metrics(t_ns, [0.0, 0.5, 1.25], 1.0, settling_band=0.25)
    assert edge.settling_time == pytest.approx(1.0 + (0.5 - 0.25) / (0.5 - 0.25), rel=1e-12)
