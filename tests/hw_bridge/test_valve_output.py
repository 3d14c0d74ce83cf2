"""Torque -> D/A code: gain, deadband compensation, saturation, rate limit, clamped flag, inverse."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from smm_hw_bridge.valve_output import ValveOutput, ValveOutputConfig

INF = (math.inf, math.inf)


def test_gain_and_rounding() -> None:
    output = ValveOutput(ValveOutputConfig(gain=(1000.0, 2000.0), rate_limit=INF))
    sample = output.step([1.2344, -0.5], 1e-3)
    assert sample.codes == (1234, -1000)
    np.testing.assert_allclose(sample.torque, np.array(sample.codes) / [1000.0, 2000.0])
    assert not sample.clamped.any()


def test_deadband_offset_outside_the_blend_band_and_linear_inside() -> None:
    config = ValveOutputConfig(
        gain=(1000.0, 1000.0), deadband=(300.0, 300.0), deadband_blend=50.0, rate_limit=INF
    )
    output = ValveOutput(config)
    assert output.step([1.0, -1.0], 1e-3).codes == (1300, -1300)
    # inside the band: demand 25 codes -> 25 * (50 + 300) / 50 = 175 codes, continuous at +-50 -> 350
    assert output.step([0.025, 0.05], 1e-3).codes == (175, 350)
    assert output.step([0.0, 0.0], 1e-3).codes == (0, 0)
    # the reported torque is the demand the codes stand for (the inverse map)
    np.testing.assert_allclose(output.step([0.7, -0.02], 1e-3).torque, [0.7, -0.02], atol=1e-3)


def test_saturation_sets_clamped_and_reports_the_clamped_torque() -> None:
    output = ValveOutput(ValveOutputConfig(gain=(1000.0, 1000.0), code_limit=(5000, 32767), rate_limit=INF))
    sample = output.step([7.0, 7.0], 1e-3)
    assert sample.codes == (5000, 7000)
    assert sample.clamped.tolist() == [True, False]
    np.testing.assert_allclose(sample.torque, [5.0, 7.0])


def test_rate_limit_per_second_of_held_command() -> None:
    output = ValveOutput(ValveOutputConfig(gain=(1000.0, 1000.0), rate_limit=(1e6, 1e6)))  # 1000 codes per ms
    codes = [output.step([10.0, -10.0], 1e-3).codes for _ in range(12)]
    assert codes[:3] == [(1000, -1000), (2000, -2000), (3000, -3000)]
    assert codes[-1] == (10000, -10000)
    assert output.step([10.0, -10.0], 1e-3).clamped.tolist() == [False, False]
    output.reset()
    sample = output.step([10.0, 0.0], 1e-3)
    assert sample.codes == (1000, 0) and sample.clamped.tolist() == [True, False]


def test_a_step_again_replaces_the_last_one_from_where_it_started() -> None:
    output = ValveOutput(ValveOutputConfig(gain=(1000.0, 1000.0), rate_limit=(1e6, 1e6)))  # 1000 codes per ms
    assert output.step_floats((10.0, -10.0), 1e-3) == (1000, -1000)
    assert output.step_floats((10.0, -10.0), 1e-3, again=True) == (1000, -1000)
    assert output.step_floats((0.5, -10.0), 1e-3, again=True) == (500, -1000)
    assert output.step_floats((10.0, -10.0), 1e-3) == (
        1500,
        -2000,
    )  # the next step starts from the replacement


def test_polarity_inverts_the_code() -> None:
    output = ValveOutput(ValveOutputConfig(gain=(1000.0, 1000.0), polarity=(-1, 1), rate_limit=INF))
    sample = output.step([1.0, 1.0], 1e-3)
    assert sample.codes == (-1000, 1000)
    np.testing.assert_allclose(sample.torque, [1.0, 1.0])


def test_null_bias_is_added_after_the_deadband_and_removed_by_the_inverse() -> None:
    config = ValveOutputConfig(
        gain=(1000.0, 1000.0), deadband=(800.0, 0.0), null_bias=(200.0, -150.0), rate_limit=INF
    )
    output = ValveOutput(config)
    assert output.step([0.0, 0.0], 1e-3).codes == (200, -150)  # no demand: the spool at its null
    sample = output.step([1.0, -1.0], 1e-3)
    assert sample.codes == (200 + 1000 + 800, -150 - 1000)
    np.testing.assert_allclose(sample.torque, [1.0, -1.0])
    np.testing.assert_allclose(output.torque_of((200, -150)), [0.0, 0.0])


def test_gain_per_direction_and_its_inverse() -> None:
    # a valve giving 0.8x its nominal torque driving q positive and 1.2x driving it negative
    nominal = 32767 / 10.0
    config = ValveOutputConfig(
        gain=(nominal / 0.8, nominal / 0.8),
        gain_negative=(nominal / 1.2, 0.0),
        polarity=(-1, 1),
        rate_limit=INF,
    )
    output = ValveOutput(config)
    sample = output.step([2.0, -2.0], 1e-3)
    assert sample.codes == (-round(2.0 * nominal / 0.8), -round(2.0 * nominal / 0.8))  # beta: 0 = gain
    sample = output.step([-2.0, 2.0], 1e-3)
    assert sample.codes == (round(2.0 * nominal / 1.2), round(2.0 * nominal / 0.8))
    np.testing.assert_allclose(sample.torque, [-2.0, 2.0], rtol=1e-4)
    np.testing.assert_allclose(
        output.torque_of((-8192, 8192)), [8192 / (nominal / 0.8), 8192 / (nominal / 0.8)]
    )
    np.testing.assert_allclose(output.torque_of((8192, -8192))[0], -8192 / (nominal / 1.2))


@pytest.mark.parametrize("torque", [[math.nan, 0.0], [math.inf, 0.0], [1.0], [[1.0, 2.0]]])
def test_bad_torque_is_rejected(torque: object) -> None:
    output = ValveOutput(ValveOutputConfig())
    with pytest.raises(ValueError):
        output.step(torque, 1e-3)  # type: ignore[arg-type]
    assert output.last.codes == (0, 0)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"gain": (0.0, 1.0)},
        {"polarity": (0, 1)},
        {"deadband": (-1.0, 0.0)},
        {"deadband_blend": 0.0},
        {"code_limit": (0, 1)},
        {"code_limit": (40000, 1)},
        {"deadband": (40000.0, 0.0)},
        {"gain_negative": (-1.0, 0.0)},
        {"null_bias": (40000.0, 0.0)},
        {"null_bias": (-2000.0, 0.0), "deadband": (800.0, 0.0), "code_limit": (2800, 32767)},
        {"rate_limit": (0.0, 1.0)},
    ],
)
def test_invalid_configs_are_rejected(kwargs: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        ValveOutputConfig(**kwargs)  # type: ignore[arg-type]


LAG = (0.02, 0.01)  # (T_rise, T_fall) (s)
PERIOD = 0.005  # a command every 5 ticks (200 Hz)


@pytest.mark.parametrize(
    ("setting", "divider", "time_constants", "expected"),
    [
        ("auto", 1, LAG, False),  # 1 kHz: the loop keeps its codes bit for bit
        ("auto", 2, LAG, True),
        ("auto", 10, LAG, True),
        ("on", 1, LAG, True),
        ("off", 5, LAG, False),
        ("on", 5, (0.0, 0.0), False),  # no lag model: nothing to compensate
    ],
)
def test_lag_compensation_auto_compensates_at_control_periods_longer_than_a_tick(
    setting: str, divider: int, time_constants: tuple[float, float], expected: bool
) -> None:
    config = ValveOutputConfig(time_constants=time_constants, lag_compensation=setting)  # type: ignore[arg-type]
    assert config.compensates_lag(divider) is expected


def test_a_compensated_code_brings_the_modelled_valve_to_the_demand_in_one_period() -> None:
    config = ValveOutputConfig(gain=(1000.0, 1000.0), rate_limit=INF, time_constants=LAG)
    output = ValveOutput(config, control_divider=5)
    # from null, opening: goal = demand / (1 - exp(-h / T_rise)); closing from there: T_fall
    first = output.step([2.0, -1.0], PERIOD)
    reached = 1.0 - math.exp(-PERIOD / LAG[0])
    assert first.codes == (round(2000.0 / reached), round(-1000.0 / reached))
    mean = output.effort(first.codes, PERIOD)  # the valve over the period, from null towards the goal
    goal = np.array(first.codes) / 1000.0
    np.testing.assert_allclose(mean, goal * (1.0 - LAG[0] / PERIOD * reached), rtol=1e-12)
    # the modelled valve is at the demand (to a code): the same demand again is its own code
    assert output.step([2.0, -1.0], PERIOD).codes == (2000, -1000)
    output.effort((2000, -1000), PERIOD)
    closing = output.step([1.5, -1.0], PERIOD).codes[0]  # the valve at 2 N m (to a code) closes with T_fall
    assert abs(closing - (2000.0 + (1500.0 - 2000.0) / (1.0 - math.exp(-PERIOD / LAG[1])))) <= 1.0


def test_without_compensation_the_code_is_the_demand_s() -> None:
    config = ValveOutputConfig(gain=(1000.0, 1000.0), rate_limit=INF, time_constants=LAG)
    off = dataclasses.replace(config, lag_compensation="off")
    for output in (ValveOutput(config), ValveOutput(off, control_divider=5)):
        assert output.step([2.0, -1.0], PERIOD).codes == (2000, -1000)


def test_a_compensated_goal_beyond_the_code_limit_is_clamped() -> None:
    config = ValveOutputConfig(gain=(1000.0, 1000.0), rate_limit=INF, time_constants=LAG)
    sample = ValveOutput(config, control_divider=5).step([9.0, 0.0], PERIOD)  # goal 9 / 0.22 N m
    assert sample.codes == (32767, 0) and sample.clamped.tolist() == [True, False]


@pytest.mark.parametrize("setting", ["", "yes", "Auto", True])
def test_an_unknown_lag_compensation_is_refused_with_the_choices(setting: object) -> None:
    with pytest.raises(ValueError, match="lag_compensation must be one of auto, on, off"):
        ValveOutputConfig(lag_compensation=setting)  # type: ignore[arg-type]
