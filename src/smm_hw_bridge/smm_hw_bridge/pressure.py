"""Load-pressure transducers (A/D channels 1 and 2) -> the joint torque the actuators give (pure, no ROS).

The torque is the chamber-pressure difference times the actuator's lever arm x piston area; the
calibration per joint is a scale and an offset of the A/D code (docs/BENCH.md, "Load pressure").
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final

from smm_schema.ranges import above, bounds, check_bounds, no_range

from smm_hw_bridge.protocol import ADC_CHANNELS, ADC_MAX

__all__ = [
    "LOAD_CHANNELS",
    "PASCAL_PER_BAR",
    "LoadTorque",
    "PressureConfig",
    "load_pressure",
    "measured_torque",
]

LOAD_CHANNELS: Final[tuple[int, int]] = (1, 2)
"""A/D channels of the load-pressure transducers (alpha, beta)."""
PASCAL_PER_BAR: Final[float] = 1e5


@dataclass(frozen=True)
class PressureConfig:
    """Calibration of the load-pressure transducers (``bridge.pressure.*``).

    Attributes:
        bar_per_code: Load pressure per A/D code (bar) (alpha, beta), finite and != 0; negative for a
            transducer that reads the chambers the other way round.
        zero_code: A/D code at a load pressure of 0 (alpha, beta), in [0, 4095].
        lever_arm_area: Lever arm times piston area of each actuator (m^3) (alpha, beta), > 0: the joint
            torque is the load pressure times it.
    """

    bar_per_code: tuple[float, float] = field(default=(25.0 / 2048.0, 25.0 / 2048.0), metadata=no_range())
    zero_code: tuple[float, float] = field(default=(2048.0, 2048.0), metadata=bounds(0.0, ADC_MAX))
    lever_arm_area: tuple[float, float] = field(default=(1.5e-5, 1.5e-5), metadata=above(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)
        if 0.0 in self.bar_per_code:
            raise ValueError(f"bar_per_code must be != 0 for both joints, got {self.bar_per_code!r}")

    @property
    def torque_per_code(self) -> tuple[float, float]:
        """Joint torque per A/D code (N m) (alpha, beta): ``bar_per_code`` * 1e5 * ``lever_arm_area``."""
        return (
            self.bar_per_code[0] * PASCAL_PER_BAR * self.lever_arm_area[0],
            self.bar_per_code[1] * PASCAL_PER_BAR * self.lever_arm_area[1],
        )


class LoadTorque:
    """A/D codes of a decoded feedback frame -> the joint torque the actuators give, per frame (no checks).

    Args:
        config: The transducers' calibration.
    """

    def __init__(self, config: PressureConfig) -> None:
        self._zero = (float(config.zero_code[0]), float(config.zero_code[1]))
        self._per_code = config.torque_per_code

    def torque(self, adc: Sequence[int]) -> tuple[float, float]:
        """Joint torque (alpha, beta) (N m) from the 4 A/D codes, which the frame's decoder checked."""
        zero, per_code = self._zero, self._per_code
        return (
            (adc[LOAD_CHANNELS[0]] - zero[0]) * per_code[0],
            (adc[LOAD_CHANNELS[1]] - zero[1]) * per_code[1],
        )


def _codes(adc: Sequence[int]) -> tuple[int, int]:
    if isinstance(adc, (str, bytes)) or len(adc) != ADC_CHANNELS:
        raise ValueError(f"adc must hold {ADC_CHANNELS} channels, got {adc!r}")
    codes = tuple(adc[channel] for channel in LOAD_CHANNELS)
    for code in codes:
        if isinstance(code, bool) or not isinstance(code, int) or not 0 <= code <= ADC_MAX:
            raise ValueError(f"load-pressure codes must be ints in [0, {ADC_MAX}], got {codes!r}")
    return codes[0], codes[1]


def load_pressure(adc: Sequence[int], config: PressureConfig) -> tuple[float, float]:
    """Load pressure (alpha, beta) (bar) from a feedback frame's A/D channels (4 codes).

    Raises:
        ValueError: not 4 channels, or a load channel not an int in [0, 4095].
    """
    codes = _codes(adc)
    return (
        (codes[0] - config.zero_code[0]) * config.bar_per_code[0],
        (codes[1] - config.zero_code[1]) * config.bar_per_code[1],
    )


def measured_torque(adc: Sequence[int], config: PressureConfig) -> tuple[float, float]:
    """Joint torque (alpha, beta) (N m) the actuators give, from a feedback frame's A/D channels.

    Raises:
        ValueError: As :func:`load_pressure`.
    """
    _codes(adc)
    return LoadTorque(config).torque(adc)
