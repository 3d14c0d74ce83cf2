"""Encoder counts -> rad against analytic values: resolution, zero offset, direction, counter wrap."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_hw_bridge.encoder import EncoderConfig, EncoderDecoder


def test_counts_to_radians_with_offset_and_direction() -> None:
    decoder = EncoderDecoder(
        EncoderConfig(counts_per_rev=(4000, 1000), zero_offset=(100, 50), direction=(1, -1))
    )
    position = decoder.update((1100, 300))
    np.testing.assert_allclose(position, [2 * math.pi * 1000 / 4000, -2 * math.pi * 250 / 1000])


def test_counter_wrap_is_unwrapped_both_ways() -> None:
    config = EncoderConfig(counts_per_rev=(1000, 1000), zero_offset=(65530, 3), counter_bits=16)
    decoder = EncoderDecoder(config)
    np.testing.assert_allclose(decoder.update((65530, 3)), [0.0, 0.0])
    # alpha counts up through the wrap (+10 counts), beta down through it (-10 counts)
    np.testing.assert_allclose(decoder.update((4, 65529)), 2 * math.pi * np.array([10, -10]) / 1000)
    np.testing.assert_allclose(decoder.update((65534, 10)), 2 * math.pi * np.array([4, 7]) / 1000)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-20000, 20000), min_size=1, max_size=50), st.integers(0, 65535))
def test_unwrapped_position_equals_the_true_count_sum(steps: list[int], offset: int) -> None:
    decoder = EncoderDecoder(
        EncoderConfig(counts_per_rev=(2000, 2000), zero_offset=(offset, offset), counter_bits=16)
    )
    true = 0
    decoder.update((offset, offset))
    for step in steps:
        true += step
        raw = (offset + true) % 65536
        position = decoder.update((raw, raw))
    assert position[0] == pytest.approx(2 * math.pi * true / 2000)


def test_reset_reads_relative_to_the_zero_offset_again() -> None:
    decoder = EncoderDecoder(EncoderConfig(counts_per_rev=(100, 100), counter_bits=8))
    decoder.update((0, 0))
    decoder.update((100, 100))
    decoder.update((200, 200))
    assert decoder.internals["counts"][0] == 200
    decoder.reset()
    assert decoder.update((200, 200))[0] == pytest.approx(2 * math.pi * -56 / 100)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"counts_per_rev": (0, 1)},
        {"direction": (0, 1)},
        {"direction": (2, 1)},
        {"counter_bits": 40},
        {"zero_offset": (70000, 0), "counter_bits": 16},
        {"counts_per_rev": (1.5, 1)},
    ],
)
def test_invalid_configs_are_rejected_with_their_field(kwargs: dict[str, object]) -> None:
    with pytest.raises(ValueError, match=next(iter(kwargs))):
        EncoderConfig(**kwargs)  # type: ignore[arg-type]


def test_out_of_range_counts_are_rejected() -> None:
    decoder = EncoderDecoder(EncoderConfig(counter_bits=16))
    with pytest.raises(ValueError):
        decoder.update((65536, 0))
