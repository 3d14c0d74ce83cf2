"""The safety stop on feedback: past soft limit + margin; a joint accelerating against its torque."""

from __future__ import annotations

import dataclasses

import pytest
from smm_hw_bridge.safety_stop import SafetyStop, SafetyStopConfig
from smm_node_runtime.parameter_check import did_you_mean, known_names

MS = 1_000_000
LIMITS = (1.2, 1.2)


def feed(
    stop: SafetyStop,
    ticks: range,
    acceleration: tuple[float, float],
    torque: tuple[float, float],
    live: bool = True,
) -> int | None:
    """Feeds joints at constant ``acceleration`` (rad/s^2) from rest; the first tick with a reason or None."""
    for tick in ticks:
        t = tick * 1e-3
        stop.on_feedback(tick, (0.5 * acceleration[0] * t * t, 0.5 * acceleration[1] * t * t), torque, live)
        if stop.reason() is not None:
            return tick
    return None


def test_a_joint_accelerating_against_its_torque_stops_after_two_windows() -> None:
    stop = SafetyStop(SafetyStopConfig(), LIMITS, MS)
    # 20 ms of torque to fill the window, then 20 ms of acceleration against it
    assert feed(stop, range(200), (0.0, -100.0), (0.0, 5.0)) == 2 * 20 - 1
    reason = stop.reason()
    assert reason is not None and reason.startswith("safety stop: joint beta accelerates at -100 rad/s^2")
    assert "+5.00 N m its valve gives, for 20 ms" in reason
    assert "bridge.limit_stop.runaway_acceleration 60 rad/s^2" in reason
    assert "bridge.valve.polarity and bridge.encoder.direction" in reason
    assert stop.reason() == reason  # latched


@pytest.mark.parametrize(
    ("acceleration", "torque", "why"),
    [
        ((0.0, 100.0), (0.0, 5.0), "with its torque"),
        ((0.0, -50.0), (0.0, 5.0), "slower than runaway_acceleration"),
        ((0.0, -100.0), (0.0, 1.9), "a torque below runaway_torque"),
        ((0.0, 0.0), (0.0, -5.0), "at rest"),
    ],
)
def test_no_stop_without_a_runaway(
    acceleration: tuple[float, float], torque: tuple[float, float], why: str
) -> None:
    assert feed(SafetyStop(SafetyStopConfig(), LIMITS, MS), range(150), acceleration, torque) is None, why


@pytest.mark.parametrize(("half_period", "stops"), [(30, False), (45, True)])
def test_a_torque_that_changes_sign_starts_the_window_again(half_period: int, stops: bool) -> None:
    """Always accelerating against a torque that flips every ``half_period`` ticks: 40 of one sign stop."""
    stop = SafetyStop(SafetyStopConfig(), LIMITS, MS)
    position = velocity = 0.0
    for tick in range(300):
        torque = 5.0 if (tick // half_period) % 2 else -5.0
        velocity -= 100.0 * 1e-3 * (1.0 if torque > 0.0 else -1.0)
        position += velocity * 1e-3
        stop.on_feedback(tick, (0.0, position), (0.0, torque), True)
        if stop.reason() is not None:
            break
    assert abs(position) < 1.0  # short of the margin
    assert (stop.reason() is not None) == stops, stop.reason()


def test_an_impact_on_a_stop_is_shorter_than_the_window() -> None:
    """A joint at 3 rad/s stops dead against the torque that drives it: one jump of speed, no runaway."""
    stop = SafetyStop(SafetyStopConfig(), LIMITS, MS)
    for tick in range(300):
        position = min(tick * 3e-3, 0.6)
        stop.on_feedback(tick, (position, 0.0), (8.0, 0.0), True)
        assert stop.reason() is None


def test_a_gap_in_the_feedback_or_an_output_not_live_restarts_the_check() -> None:
    stop = SafetyStop(SafetyStopConfig(), LIMITS, MS)
    ticks = [*range(0, 30), *range(31, 61), *range(62, 92)]  # never 40 consecutive ticks
    for tick in ticks:
        t = tick * 1e-3
        stop.on_feedback(tick, (0.0, -50.0 * t * t), (0.0, 5.0), True)
        assert stop.reason() is None
    stop = SafetyStop(SafetyStopConfig(), LIMITS, MS)
    assert feed(stop, range(150), (0.0, -100.0), (0.0, 5.0), live=False) is None


def test_a_window_of_zero_turns_the_runaway_check_off() -> None:
    stop = SafetyStop(SafetyStopConfig(runaway_window=0.0), LIMITS, MS)
    assert feed(stop, range(150), (0.0, -100.0), (0.0, 5.0)) is None


def test_past_the_soft_limit_by_the_margin_judged_ahead_at_the_speed() -> None:
    config = SafetyStopConfig(margin=0.05, lead=0.01, runaway_window=0.0)
    stop = SafetyStop(config, LIMITS, MS)
    stop.on_feedback(0, (1.24, 0.0), (0.0, 0.0), True)
    assert stop.reason() is None  # no speed yet
    stop.on_feedback(1, (1.245, 0.0), (0.0, 0.0), True)  # 5 rad/s: 1.295 rad 10 ms ahead
    reason = stop.reason()
    assert reason is not None and reason.startswith("safety stop: joint alpha reads 1.245 rad (1.295 rad")
    assert "bridge.limit_stop.lead 0.01 s ahead), past its soft limit 1.2 rad by more than" in reason
    without_lead = SafetyStop(dataclasses.replace(config, lead=0.0), LIMITS, MS)
    without_lead.on_feedback(0, (1.24, 0.0), (0.0, 0.0), True)
    without_lead.on_feedback(1, (1.245, 0.0), (0.0, 0.0), True)
    assert without_lead.reason() is None
    without_lead.on_feedback(2, (0.0, -1.2501), (0.0, 0.0), False)  # judged also while not live
    assert without_lead.reason() is not None and "joint beta reads -1.250 rad" in str(without_lead.reason())
    without_lead.reset()
    assert without_lead.reason() is None


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"margin": 0.0}, "margin"),
        ({"lead": -0.01}, "lead"),
        ({"runaway_torque": 0.0}, "runaway_torque"),
        ({"runaway_acceleration": float("nan")}, "runaway_acceleration"),
        ({"runaway_window": 1.5}, "runaway_window"),
    ],
)
def test_invalid_settings_are_rejected_with_their_name(kwargs: dict[str, float], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        SafetyStopConfig(**kwargs)


def test_the_old_parameter_names_are_refused_naming_the_new_ones() -> None:
    known = known_names("hw_bridge_node")
    assert "bridge.limit_stop_margin" not in known and "bridge.limit_stop_lead" not in known
    assert did_you_mean("bridge.limit_stop_margin", known) == "; did you mean 'bridge.limit_stop.margin'?"
    assert did_you_mean("bridge.limit_stop_lead", known) == "; did you mean 'bridge.limit_stop.lead'?"


def test_an_activation_forgets_a_runaway_but_not_the_last_reading() -> None:
    """Lockstep: the board re-sends the feedback it has until the output is live; arming must judge it."""
    stop = SafetyStop(SafetyStopConfig(), LIMITS, MS)
    assert feed(stop, range(200), (0.0, -100.0), (0.0, 5.0)) is not None
    stop.arm()
    assert stop.reason() is None
    stop.on_feedback(500, (5.992, 0.0), (0.0, 0.0), False)
    stop.arm()
    assert str(stop.reason()).startswith("safety stop: joint alpha reads 5.992 rad")
