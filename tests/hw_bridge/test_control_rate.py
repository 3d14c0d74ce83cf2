"""Control rates below the board tick: the divider, the control ticks, the validity and limits set from N."""

from __future__ import annotations

import dataclasses
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st
from smm_hw_bridge.control_rate import (
    CONTROL_RATES_HZ,
    control_divider,
    held_ticks,
    in_flight_ticks,
    is_control_tick,
)
from smm_hw_bridge.core import BridgeConfig, BridgeCore, Refusal

from tests.hw_bridge.test_core import CONFIG, HOST, MS, Board

RULE = "control rate must be one of 1000, 500, 250, 200, 100 Hz"


def test_the_offered_rates_divide_the_board_tick() -> None:
    assert [control_divider(rate) for rate in CONTROL_RATES_HZ] == [1, 2, 4, 5, 10]
    assert control_divider(500.0) == 2  # argparse gives floats


@pytest.mark.parametrize(
    "rate", [300, 0, -250, 333, 50, 125, 2000, math.nan, math.inf, -math.inf, True, "500", None, 250.5]
)
def test_a_rate_that_is_not_offered_is_refused_with_the_valid_ones(rate: object) -> None:
    with pytest.raises(ValueError, match=RULE) as raised:
        control_divider(rate)
    assert repr(rate) in str(raised.value)


@given(st.integers(min_value=0, max_value=2**32 - 1), st.sampled_from([1, 2, 4, 10]))
def test_control_ticks_are_the_multiples_of_n_so_each_period_has_exactly_one(tick: int, divider: int) -> None:
    window = [is_control_tick(tick + offset, divider) for offset in range(divider)]
    assert sum(window) == 1


@pytest.mark.parametrize(
    ("divider", "validity", "stale", "watchdog_ms"),
    [(1, 10, 5, 10), (2, 12, 6, 12), (4, 16, 8, 16), (5, 18, 9, 18), (10, 28, 14, 28)],
)
def test_validity_stale_limit_and_host_watchdog_grow_with_the_divider(
    divider: int, validity: int, stale: int, watchdog_ms: int
) -> None:
    config = dataclasses.replace(CONFIG, control_divider=divider)
    assert (config.validity, config.stale_ticks, config.watchdog_ns) == (validity, stale, watchdog_ms * MS)
    assert validity - held_ticks(divider) == CONFIG.validity_ticks  # the same margin at every rate
    assert stale - in_flight_ticks(divider) == CONFIG.stale_periods


@pytest.mark.parametrize("divider", [0, 11, -1, 1.5, True, "2"])
def test_a_bad_divider_is_refused_with_its_name(divider: object) -> None:
    with pytest.raises(ValueError, match="control_divider"):
        BridgeConfig(control_divider=divider)  # type: ignore[arg-type]


def test_a_validity_that_would_not_fit_the_frame_at_this_divider_is_refused() -> None:
    assert BridgeConfig(validity_ticks=65535).validity == 65535
    with pytest.raises(ValueError, match="validity_ticks must be <= 65529 at control_divider 4"):
        BridgeConfig(validity_ticks=65535, control_divider=4)


def armed_at(divider: int) -> tuple[BridgeCore, Board]:
    """A core at ``divider`` armed by a command answering control tick ``divider``."""
    core = BridgeCore(dataclasses.replace(CONFIG, control_divider=divider), HOST)
    board = Board(core)
    board.step()  # tick 0
    core.arm()
    while board.tick <= divider:
        board.step()
    assert core.control_tick
    assert core.on_command([0.5, -0.25], board.stamp, board.now) is None
    return core, board


@pytest.mark.parametrize("divider", [1, 2, 4])
def test_only_multiples_of_n_are_control_ticks(divider: int) -> None:
    core, board = armed_at(divider)
    flags = []
    for _ in range(2 * divider):
        board.step()
        flags.append(core.control_tick)
    assert flags == [(offset + 1) % divider == 0 for offset in range(2 * divider)]


@pytest.mark.parametrize("divider", [1, 2, 4])
def test_a_command_is_held_through_its_period_and_a_late_next_one_then_expires_on_the_host(
    divider: int,
) -> None:
    core, board = armed_at(divider)
    frame = core.next_frame(board.now)
    assert frame is not None and frame.enabled and frame.validity == CONFIG.validity_ticks + 2 * (divider - 1)
    # the board holds it; the host needs to send nothing new while it is valid (between control ticks too)
    for age in range(1, frame.validity + 1):
        board.step()
        assert not core.needs_frame(board.now - MS), age
    board.step()
    assert core.needs_frame(board.now - MS)  # past its validity: the host's next frame is a safe one
    safe = core.next_frame(board.now - MS)
    assert safe is not None and not safe.enabled


def test_an_answer_in_flight_for_its_whole_period_is_not_stale_at_n_4() -> None:
    core, board = armed_at(4)
    stamp = board.stamp  # control tick 8 after the next four ticks
    for _ in range(4):
        board.step()
    control = board.stamp
    for _ in range(4 + CONFIG.stale_periods - 1):
        board.step()  # the answer to `control` has been in flight for its period and the 1 kHz margin
    assert core.on_command([0.1, 0.1], control, board.now) is None
    board.step()
    assert core.on_command([0.1, 0.1], control, board.now) is Refusal.STALE
    assert stamp < control


@pytest.mark.parametrize("divider", [1, 2, 4, 5, 10])
def test_the_valve_rate_limit_allows_its_slew_per_control_period_not_per_board_tick(divider: int) -> None:
    """1000 codes a ms: a command a period of N ms may move the codes 1000 N (N = 5: 1000 slewed full
    scale in 10 ms instead of 2, and the loop on the emulated bench went unstable)."""
    valve = dataclasses.replace(CONFIG.valve, rate_limit=(1e6, 1e6))
    core = BridgeCore(dataclasses.replace(CONFIG, control_divider=divider, valve=valve), HOST)
    board = Board(core)
    board.step()
    core.arm()
    while board.tick <= divider:
        board.step()
    assert core.on_command([0.5, -0.25], board.stamp, board.now) is None  # 500 / -250 codes: within
    for _ in range(divider):
        board.step()
    assert core.control_tick
    assert core.on_command([20.0, -20.0], board.stamp, board.now) is None  # 20000 / -20000 codes asked
    frame = core.next_frame(board.now)
    assert frame is not None and frame.enabled
    assert frame.codes == (500 + 1000 * divider, -250 - 1000 * divider)


@pytest.mark.parametrize("divider", [2, 5, 10])
def test_the_effort_at_a_control_tick_is_the_mean_over_its_period_on_both_links(divider: int) -> None:
    """The observer's applied torque is the valves' over the control period: the frame link's N feedbacks
    of one tick give what the CANopen link's one feedback of N ticks gives (first-order lag from null)."""
    lag = (0.02, 0.01)
    valve = dataclasses.replace(CONFIG.valve, time_constants=lag)
    config = dataclasses.replace(CONFIG, control_divider=divider, valve=valve)
    h = divider * 1e-3
    expected = [goal * (1.0 - lag[0] / h * (1.0 - math.exp(-h / lag[0]))) for goal in (2.0, -1.0)]
    efforts = []
    for ticks_per_feedback in (1, divider):  # frame link, CANopen link
        core = BridgeCore(config, HOST)
        board = Board(core)
        while board.tick <= divider:  # the valves at null up to control tick N
            board.step()
            board.tick += ticks_per_feedback - 1
        while board.tick <= 2 * divider:  # then at (2, -1) N m for the period up to control tick 2 N
            board.step(output_codes=(2000, -1000))
            board.tick += ticks_per_feedback - 1
        assert core.control_tick and core.last_feedback is not None
        assert core.last_feedback.tick == 2 * divider
        efforts.append(core.applied_torque)
    for effort in efforts:
        assert effort == pytest.approx(expected, rel=1e-12)
