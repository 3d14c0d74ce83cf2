"""Load-pressure codes -> measured joint torque: scale, offset, lever arm x area; bad frames refused."""

from __future__ import annotations

import math

import pytest
from smm_hw_bridge.pressure import PressureConfig, load_pressure, measured_torque


def test_torque_is_the_calibrated_pressure_times_lever_arm_area() -> None:
    config = PressureConfig(
        bar_per_code=(0.01, -0.02), zero_code=(2000.0, 2100.0), lever_arm_area=(1e-5, 2e-5)
    )
    adc = (1638, 2200, 2000, 2048)  # channel 0 (supply) and 3 play no part
    assert load_pressure(adc, config) == pytest.approx((2.0, 2.0))  # beta's transducer reads reversed
    assert measured_torque(adc, config) == pytest.approx((2.0 * 1e5 * 1e-5, 2.0 * 1e5 * 2e-5))
    assert measured_torque((0, 2048, 2048, 0), PressureConfig()) == (0.0, 0.0)


@pytest.mark.parametrize(
    "adc", [(0, 1, 2), (0, 4096, 2048, 0), (0, -1, 2048, 0), (0, 2048.0, 2048, 0), (0, True, 2048, 0), "abcd"]
)
def test_malformed_channels_are_refused(adc: object) -> None:
    with pytest.raises(ValueError):
        measured_torque(adc, PressureConfig())  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"bar_per_code": (0.0, 0.01)},
        {"bar_per_code": (math.nan, 0.01)},
        {"zero_code": (5000.0, 2048.0)},
        {"lever_arm_area": (0.0, 1e-5)},
    ],
)
def test_invalid_calibrations_are_refused(kwargs: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        PressureConfig(**kwargs)  # type: ignore[arg-type]
