"""Encoder counts -> joint angle: counts per revolution, zero offset, direction, counter wrap. No ROS."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from smm_schema.ranges import bounds, check_bounds

__all__ = ["EncoderConfig", "EncoderDecoder"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class EncoderConfig:
    """How the board's encoder counters map to joint angles.

    Attributes:
        counts_per_rev: Counts per joint revolution (alpha, beta), >= 1.
        zero_offset: Raw counter value at q = 0 (alpha, beta), in [0, 2**counter_bits).
        direction: +1 if the counter counts up as q grows, -1 if down (alpha, beta).
        counter_bits: Width of the board's counters, in [8, 32]; they wrap modulo 2**counter_bits.
    """

    counts_per_rev: tuple[int, int] = field(default=(1 << 20, 1 << 20), metadata=bounds(1, 1 << 31))
    zero_offset: tuple[int, int] = field(default=(0, 0), metadata=bounds(0, (1 << 32) - 1))
    direction: tuple[int, int] = field(default=(1, 1), metadata=bounds(-1, 1))
    counter_bits: int = field(default=32, metadata=bounds(8, 32))

    def __post_init__(self) -> None:
        check_bounds(self)
        if any(offset >= 1 << self.counter_bits for offset in self.zero_offset):
            raise ValueError(f"zero_offset must be below 2**counter_bits, got {self.zero_offset!r}")
        if 0 in self.direction:
            raise ValueError(f"direction must be +1 or -1 per joint, got {self.direction!r}")

    @property
    def modulus(self) -> int:
        """2**counter_bits: raw counter values are in [0, modulus)."""
        return 1 << self.counter_bits

    @property
    def quantum(self) -> FloatArray:
        """Angle of one count (rad), shape (2,)."""
        return 2.0 * math.pi / np.asarray(self.counts_per_rev, dtype=np.float64)


class EncoderDecoder:
    """Unwraps raw counter values and converts them to joint angles (rad).

    Between two samples a counter is assumed to move by less than half its range (2**(bits-1) counts).
    The angle is computed once per sample as Python floats; :attr:`position` builds its array when read.
    """

    def __init__(self, config: EncoderConfig) -> None:
        self._config = config
        self._modulus = config.modulus
        self._half = self._modulus >> 1
        quantum = 2.0 * math.pi
        self._scale = (
            (float(config.direction[0]), quantum / float(config.counts_per_rev[0])),
            (float(config.direction[1]), quantum / float(config.counts_per_rev[1])),
        )
        self.reset()

    @property
    def config(self) -> EncoderConfig:
        """The configuration."""
        return self._config

    def reset(self) -> None:
        """Forgets the counter history: the next sample is read relative to ``zero_offset`` again."""
        self._raw: tuple[int, int] | None = None
        self._counts = [0, 0]
        self._position = self._angles()

    def _signed(self, delta: int) -> int:
        return ((delta + self._half) % self._modulus) - self._half

    def update_floats(self, raw: tuple[int, int]) -> tuple[float, float]:
        """:meth:`update`, returning the angle as Python floats (alpha, beta) (rad).

        Raises:
            ValueError: A counter value outside [0, 2**counter_bits).
        """
        modulus = self._modulus
        for value in raw:
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < modulus:
                raise ValueError(f"raw counts must be ints in [0, {modulus}), got {raw!r}")
        previous = self._raw
        if previous is None:
            offset = self._config.zero_offset
            counts = [self._signed(raw[0] - offset[0]), self._signed(raw[1] - offset[1])]
        else:
            counts = [
                self._counts[0] + self._signed(raw[0] - previous[0]),
                self._counts[1] + self._signed(raw[1] - previous[1]),
            ]
        self._counts = counts
        self._raw = (raw[0], raw[1])
        self._position = self._angles()
        return self._position

    def _angles(self) -> tuple[float, float]:
        # the order of the numpy expression direction * counts * quantum, so the floats agree bit for bit
        (direction_a, quantum_a), (direction_b, quantum_b) = self._scale
        return (
            direction_a * float(self._counts[0]) * quantum_a,
            direction_b * float(self._counts[1]) * quantum_b,
        )

    def update(self, raw: tuple[int, int]) -> FloatArray:
        """Takes one pair of raw counter values and returns the joint angle (alpha, beta) (rad).

        Raises:
            ValueError: A counter value outside [0, 2**counter_bits).
        """
        self.update_floats(raw)
        return self.position

    @property
    def position_floats(self) -> tuple[float, float]:
        """Last joint angle (alpha, beta) (rad) as Python floats; zeros before the first sample."""
        return self._position

    @property
    def position(self) -> FloatArray:
        """Last joint angle (alpha, beta) (rad); zeros before the first sample."""
        return np.array(self._position, dtype=np.float64)

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """``counts``: unwrapped counts from the zero offset (direction applied), shape (2,)."""
        return {
            "counts": np.asarray(self._config.direction, dtype=np.float64) * np.asarray(self._counts, float)
        }
