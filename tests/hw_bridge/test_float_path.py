"""The bridge's Python-float per-frame path agrees bit for bit with the numpy arithmetic it replaced.

The numpy reference below is the valve output, encoder angle and soft-limit cut as they were written on
2-element arrays; the bridge now computes the same operations in the same order on Python floats.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from smm_dynamics.valve import valve_lag_step
from smm_hw_bridge.core import BridgeConfig, BridgeCore, BridgeState, Refusal
from smm_hw_bridge.encoder import EncoderConfig, EncoderDecoder
from smm_hw_bridge.link import AdmissionConfig
from smm_hw_bridge.protocol import CODE_MAX, CommandFlag, FeedbackFrame, encode
from smm_hw_bridge.valve_output import ValveOutput, ValveOutputConfig

FloatArray = npt.NDArray[np.float64]
HOST = 0x0BAD_CAFE
BOARD = 0x0000_1234


class NumpyValveOutput:
    """Reference: the valve output's arithmetic on numpy 2-vectors (np.sign, np.clip, np.rint)."""

    def __init__(self, config: ValveOutputConfig) -> None:
        self.config = config
        polarity = np.asarray(config.polarity, dtype=np.float64)
        self.gain = np.asarray(config.gain, dtype=np.float64) * polarity
        negative = np.where(np.asarray(config.gain_negative) > 0.0, config.gain_negative, config.gain)
        self.gain_negative = negative.astype(np.float64) * polarity
        self.bias = np.asarray(config.null_bias, dtype=np.float64)
        self.deadband = np.asarray(config.deadband, dtype=np.float64)
        self.limit = np.asarray(config.code_limit, dtype=np.float64)
        self.rate = np.asarray(config.rate_limit, dtype=np.float64)
        self.last = np.zeros(2)
        self.valve = [0.0, 0.0]

    def compensate(self, demand: FloatArray) -> FloatArray:
        blend = self.config.deadband_blend
        magnitude = np.abs(demand)
        outside = np.sign(demand) * (magnitude + self.deadband)
        inside = demand * (blend + self.deadband) / blend
        return np.where(magnitude >= blend, outside, inside)

    def uncompensate(self, code: FloatArray) -> FloatArray:
        blend = self.config.deadband_blend
        magnitude = np.abs(code)
        edge = blend + self.deadband
        outside = np.sign(code) * (magnitude - self.deadband)
        inside = code * blend / edge
        return np.where(magnitude >= edge, outside, inside)

    def step(
        self, torque: FloatArray, dt: float
    ) -> tuple[tuple[int, int], FloatArray, npt.NDArray[np.bool_]]:
        with np.errstate(all="ignore"):  # a huge demand overflows to inf on both paths
            wanted = (
                self.compensate(torque * np.where(torque >= 0.0, self.gain, self.gain_negative)) + self.bias
            )
        saturated = np.clip(wanted, -self.limit, self.limit)
        step = self.rate * dt
        limited = np.clip(saturated, self.last - step, self.last + step)
        codes = np.clip(np.rint(limited), -self.limit, self.limit)
        clamped = (saturated != wanted) | (limited != saturated)
        self.last = codes
        pair = (int(codes[0]), int(codes[1]))
        return pair, self.torque_of(pair), clamped

    def torque_of(self, codes: tuple[int, int]) -> FloatArray:
        opening = self.uncompensate(np.asarray(codes, dtype=np.float64) - self.bias)
        torque = opening / self.gain
        return np.where(torque < 0.0, opening / self.gain_negative, torque)

    def effort(self, codes: tuple[int, int], dt: float) -> FloatArray:
        target = self.torque_of(codes)
        rise, fall = self.config.time_constants
        if rise == 0.0:
            return target
        mean = np.empty(2)
        for joint in range(2):
            self.valve[joint], mean[joint] = valve_lag_step(
                self.valve[joint], float(target[joint]), dt, rise, fall
            )
        return mean


def numpy_position(config: EncoderConfig, counts: list[int]) -> FloatArray:
    """Reference: the encoder angle as it was computed on arrays (rad)."""
    quantum = 2.0 * math.pi / np.asarray(config.counts_per_rev, dtype=np.float64)
    return np.asarray(config.direction, dtype=np.float64) * np.asarray(counts, dtype=np.float64) * quantum


def same_bits(actual: object, expected: object) -> bool:
    """True if both are float64 pairs with the same bits (0.0 and -0.0 differ)."""
    return bool(
        np.asarray(actual, dtype=np.float64).tobytes() == np.asarray(expected, dtype=np.float64).tobytes()
    )


finite = st.floats(allow_nan=False, allow_infinity=False)
torques = st.one_of(
    finite,
    st.floats(-100.0, 100.0),
    st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 1e-3, -1e-3, 32.767, -32.767]),
)
pairs = st.tuples(torques, torques)
positive = st.floats(1e-3, 1e5, allow_nan=False)
valve_configs = st.builds(
    ValveOutputConfig,
    gain=st.tuples(positive, positive),
    gain_negative=st.tuples(st.one_of(st.just(0.0), positive), st.one_of(st.just(0.0), positive)),
    null_bias=st.tuples(st.sampled_from([0.0, 200.0, -37.5]), st.floats(-400.0, 400.0)),
    polarity=st.tuples(st.sampled_from([1, -1]), st.sampled_from([1, -1])),
    deadband=st.tuples(st.floats(0.0, 500.0), st.sampled_from([0.0, 100.0, 0.5])),
    deadband_blend=st.floats(1e-3, 1000.0),
    code_limit=st.tuples(st.integers(1000, CODE_MAX), st.integers(1000, CODE_MAX)),
    rate_limit=st.tuples(
        st.one_of(st.just(math.inf), st.floats(1e-300, 1e9)), st.one_of(st.just(math.inf), positive)
    ),
    time_constants=st.one_of(st.just((0.0, 0.0)), st.tuples(st.floats(1e-4, 0.1), st.floats(1e-4, 0.1))),
)
dts = st.one_of(st.floats(1e-9, 1.0), st.sampled_from([1e-3, 1e-300, 5e-324]))
codes = st.tuples(st.integers(-CODE_MAX, CODE_MAX), st.integers(-CODE_MAX, CODE_MAX))


@given(st.one_of(finite, st.integers(-(1 << 20), 1 << 20).map(lambda n: n + 0.5)))
@example(0.5)
@example(-2.5)
@example(4503599627370495.5)  # the largest float with a fraction: a tie, rounded to even
@example(-0.49999999999999994)
def test_python_round_is_np_rint_for_every_finite_float(value: float) -> None:
    assert float(round(value)) == np.rint(value)


@settings(max_examples=300)
@given(valve_configs, st.lists(st.tuples(pairs, dts, st.booleans()), min_size=1, max_size=12))
def test_valve_step_is_bit_for_bit_the_numpy_map(
    config: ValveOutputConfig, commands: list[tuple[tuple[float, float], float, bool]]
) -> None:
    output, reference = ValveOutput(config), NumpyValveOutput(config)
    for torque, dt, checked in commands:
        expected_codes, expected_torque, expected_clamped = reference.step(np.asarray(torque), dt)
        if checked:  # both call shapes: the checked array-like and the caller-checked floats
            sample = output.step(list(torque), dt)
        else:
            output.step_floats(torque, dt)
            sample = output.last
        assert sample.codes == expected_codes
        assert same_bits(sample.torque, expected_torque)
        assert sample.clamped.tolist() == expected_clamped.tolist()
        internals = output.internals
        assert same_bits(internals["codes"], np.asarray(expected_codes, dtype=np.float64))
        assert same_bits(internals["torque"], expected_torque)
        assert same_bits(internals["clamped"], expected_clamped.astype(np.float64))


@settings(max_examples=200)
@given(valve_configs, st.lists(st.tuples(codes, dts, st.booleans()), min_size=1, max_size=12))
def test_valve_effort_and_inverse_are_bit_for_bit_the_numpy_ones(
    config: ValveOutputConfig, ticks: list[tuple[tuple[int, int], float, bool]]
) -> None:
    output, reference = ValveOutput(config), NumpyValveOutput(config)
    for pair, dt, as_array in ticks:
        assert same_bits(output.torque_of(pair), reference.torque_of(pair))
        expected = reference.effort(pair, dt)
        if as_array:
            assert same_bits(output.effort(pair, dt), expected)
        else:
            assert same_bits(output.effort_floats(pair, dt), expected)


@settings(max_examples=200)
@given(
    st.builds(
        EncoderConfig,
        counts_per_rev=st.tuples(st.integers(1, 1 << 31), st.integers(1, 1 << 31)),
        zero_offset=st.tuples(st.integers(0, (1 << 16) - 1), st.integers(0, (1 << 16) - 1)),
        direction=st.tuples(st.sampled_from([1, -1]), st.sampled_from([1, -1])),
        counter_bits=st.integers(16, 32),
    ),
    st.lists(st.tuples(st.integers(0, (1 << 16) - 1), st.integers(0, (1 << 16) - 1)), max_size=10),
)
def test_encoder_angle_is_bit_for_bit_the_numpy_one(
    config: EncoderConfig, raws: list[tuple[int, int]]
) -> None:
    decoder = EncoderDecoder(config)
    assert same_bits(decoder.position, numpy_position(config, [0, 0]))
    for raw in raws:
        angle = decoder.update(raw)
        counts = [int(c) for c in decoder.internals["counts"] * np.asarray(config.direction)]
        expected = numpy_position(config, counts)
        assert same_bits(angle, expected)
        assert same_bits(decoder.position, expected)
        assert same_bits(decoder.position_floats, expected)
    decoder.reset()
    assert same_bits(decoder.position_floats, numpy_position(config, [0, 0]))


def feedback(seq: int, counts: tuple[int, int], output_codes: tuple[int, int]) -> bytes:
    """A feedback frame of board tick ``seq - 1`` from a board locked to ``HOST``."""
    return encode(
        FeedbackFrame(
            session=BOARD,
            seq=seq,
            tick=seq - 1,
            host_session=HOST,
            counts=counts,
            adc=(1600, 0, 0, 0),
            status=0,
            faults=0,
            applied_seq=0,
            applied_age=0xFFFF,
            output_codes=output_codes,
            late_commands=0,
            crc_errors=0,
            dropped_frames=0,
        )
    )


SHAPES = ("tuple", "list", "array", "np_floats")


def shaped(torque: tuple[float, float], shape: str) -> object:
    """The same demand as each kind of array-like ``on_command`` takes."""
    if shape == "tuple":
        return torque
    if shape == "list":
        return list(torque)
    if shape == "array":
        return np.asarray(torque)
    return (np.float64(torque[0]), np.float64(torque[1]))


@settings(max_examples=150)
@given(
    valve_configs,
    st.tuples(st.floats(0.01, 3.0), st.floats(0.01, 3.0)),
    st.sampled_from([1_000_000, 1_000, 3_333_333]),
    st.lists(
        st.tuples(
            st.tuples(st.integers(-3000, 3000), st.integers(-3000, 3000)),
            pairs,
            codes,
            st.sampled_from(SHAPES),
        ),
        min_size=1,
        max_size=8,
    ),
)
def test_core_command_and_effort_are_bit_for_bit_the_numpy_ones(
    valve: ValveOutputConfig,
    limits: tuple[float, float],
    period_ns: int,
    ticks: list[tuple[tuple[int, int], tuple[float, float], tuple[int, int], str]],
) -> None:
    encoder = EncoderConfig(counts_per_rev=(4096, 4096), direction=(1, -1))
    config = BridgeConfig(
        encoder=encoder,
        valve=valve,
        admission=AdmissionConfig(period_ns=period_ns, stale_ns=10**10),
        host_watchdog_ns=10**10,
        soft_limits=limits,
    )
    core = BridgeCore(config, host_session=HOST)
    reference, lag = NumpyValveOutput(valve), NumpyValveOutput(valve)
    now = 0
    assert core.on_datagram(feedback(1, (0, 0), (0, 0)), now) is not None
    lag.effort((0, 0), period_ns / 1e9)
    core.arm()
    lag.valve = [0.0, 0.0]  # arming resets the lag model (code 0 is no null with a null bias)
    for seq, (counts, torque, reported, shape) in enumerate(ticks, start=2):
        now += period_ns
        raw = (counts[0] % (1 << 32), counts[1] % (1 << 32))
        assert core.on_datagram(feedback(seq, raw, reported), now) is not None
        position = numpy_position(encoder, list(counts))
        effort = lag.effort(reported, period_ns / 1e9)
        assert same_bits(core.position, position) and same_bits(core.position_floats, position)
        assert same_bits(core.applied_torque, effort) and same_bits(core.applied_torque_floats, effort)
        assert core.on_command(shaped(torque, shape), core.stamp_ns, now) is None  # type: ignore[arg-type]
        demand, bound = np.asarray(torque), np.asarray(limits)
        cut = ((position >= bound) & (demand > 0.0)) | ((position <= -bound) & (demand < 0.0))
        expected_codes, expected_torque, expected_clamped = reference.step(
            np.where(cut, 0.0, demand), period_ns * 1e-9
        )
        frame = core.next_frame(now)
        assert frame is not None and frame.flags == CommandFlag.ENABLE and frame.codes == expected_codes
        internals = core.internals
        assert same_bits(internals["torque"], expected_torque)
        assert same_bits(internals["clamped"], expected_clamped.astype(np.float64))
        assert same_bits(internals["limit_cut"], cut.astype(np.float64))
        assert core.state == BridgeState.ARMED


@pytest.mark.parametrize(
    "torque",
    [
        (math.nan, 0.0),
        [0.0, math.inf],
        (-math.inf, 1.0),
        (1.0,),
        (1.0, 2.0, 3.0),
        [[1.0, 2.0]],
        "12",
        (np.float64(math.nan), 0.0),
        np.array([1.0, math.nan]),
    ],
)
def test_core_refuses_every_kind_of_bad_torque_and_changes_nothing(torque: object) -> None:
    core = BridgeCore(BridgeConfig(), host_session=HOST)
    core.on_datagram(feedback(1, (0, 0), (0, 0)), 0)
    core.arm()
    core.on_datagram(feedback(2, (0, 0), (0, 0)), 1_000_000)
    before = core.internals
    assert core.on_command(torque, core.stamp_ns, 1_000_000) is Refusal.INVALID  # type: ignore[arg-type]
    assert core.refused == {Refusal.INVALID: 1} and core.state == BridgeState.ARMING
    assert all(same_bits(core.internals[key], value) for key, value in before.items())
    assert core.on_command((0.5, -0.5), True, 1_000_000) is Refusal.INVALID  # a bool is no stamp
    assert core.on_command((0.5, -0.5), core.stamp_ns, 1_000_000) is None
    assert core.state == BridgeState.ARMED
