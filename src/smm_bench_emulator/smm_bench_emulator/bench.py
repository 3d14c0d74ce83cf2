"""The emulated bench's truths besides the plant: valves, actuators, encoders, supply, A/D (docs/BENCH.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Final

from smm_dynamics.model import mass_matrix
from smm_hw_bridge.protocol import ADC_MAX, CODE_MAX
from smm_schema.ranges import above, at_least, bounds, check_bounds
from smm_sim.plant import PlantConfig

__all__ = ["BenchSettings", "check_lock_stability"]

# The lock is integrated explicitly once per tick: its natural frequency times the tick, and its damping
# per inertia times the tick, must stay below these for the held joint to settle (docs/BENCH.md).
_LOCK_OMEGA_DT_MAX: Final[float] = 0.5
_LOCK_DAMPING_DT_MAX: Final[float] = 1.0
_INERTIA_SAMPLES: Final[int] = 16


@dataclass(frozen=True)
class BenchSettings:
    """The bench's truths the board emulates besides the plant's dynamics (alpha, beta per joint).

    Attributes:
        zero_offset: Raw counter value at q = 0 (alpha, beta), in [0, 2**counter_bits).
        direction: +1 if a counter counts up as q grows, -1 if down (alpha, beta).
        counter_bits: Width of the encoder counters, in [8, 32].
        full_scale_torque: Joint torque at a spool opening of 32767 codes and nominal supply (N m) (alpha,
            beta), > 0; the gain per direction scales it.
        valve_deadband: Valve overlap (codes) (alpha, beta), >= 0: a spool within it of null passes no oil
            and the joint is held by the trapped oil (lock_*); 0 = a zero-lapped valve, never locked while
            enabled.
        valve_polarity: +1 if a positive spool opening drives q positive, -1 if negative (alpha, beta).
        valve_null_bias: D/A code at which the spool is at null (codes) (alpha, beta), in [-32767, 32767].
        valve_gain_positive: Factor on full_scale_torque when the valve drives q positive (alpha, beta), > 0.
        valve_gain_negative: Factor on full_scale_torque when the valve drives q negative (alpha, beta), > 0.
        lock_stiffness: Stiffness of the trapped oil column, as a joint torque per radian (N m/rad) (alpha,
            beta), > 0.
        lock_damping: Damping of the locked joint (N m s/rad) (alpha, beta), >= 0.
        lock_leakage: Leakage drift of the locked joint per N m it holds (rad/s per N m) (alpha, beta), >= 0:
            a joint holding a load L drifts at most lock_leakage * L rad/s.
        lever_arm_area: Lever arm times piston area of each actuator (m^3) (alpha, beta), > 0: the load
            pressure is the actuator's torque divided by it.
        load_zero_code: A/D code of a load pressure of 0 on channels 1 (alpha) and 2 (beta), in [0, 4095].
        load_bar_per_code: Load pressure per A/D code on channels 1 and 2 (bar) (alpha, beta), > 0.
        supply_pressure: Supply pressure (bar), >= 0; the valve's torque scales with sqrt(p / nominal).
        nominal_pressure: Pressure at which ``full_scale_torque`` holds (bar), > 0.
        supply_low: Below this pressure the board sets SUPPLY_LOW and nulls the valves (bar), >= 0.
        bar_per_code: Supply pressure per A/D code of channel 0 (bar), > 0.
        adc_noise: Standard deviation of the A/D noise on every channel (codes), >= 0.
        ramp_ticks: Ticks the watchdog ramp takes from full scale to null, >= 1. The default 1 puts the
            D/A at null on the first tick past validity; the valve's own lag then closes the spool smoothly.
        seed: Seed of the A/D noise, >= 0 (the session ids are random: a restart must look new).
    """

    zero_offset: tuple[int, int] = field(default=(0, 0), metadata=bounds(0, (1 << 32) - 1))
    direction: tuple[int, int] = field(default=(1, 1), metadata=bounds(-1, 1))
    counter_bits: int = field(default=32, metadata=bounds(8, 32))
    full_scale_torque: tuple[float, float] = field(default=(10.0, 10.0), metadata=above(0.0))
    valve_deadband: tuple[float, float] = field(default=(0.0, 0.0), metadata=bounds(0.0, CODE_MAX))
    valve_polarity: tuple[int, int] = field(default=(1, 1), metadata=bounds(-1, 1))
    valve_null_bias: tuple[float, float] = field(default=(0.0, 0.0), metadata=bounds(-CODE_MAX, CODE_MAX))
    valve_gain_positive: tuple[float, float] = field(default=(1.0, 1.0), metadata=above(0.0))
    valve_gain_negative: tuple[float, float] = field(default=(1.0, 1.0), metadata=above(0.0))
    lock_stiffness: tuple[float, float] = field(default=(2000.0, 2000.0), metadata=above(0.0))
    lock_damping: tuple[float, float] = field(default=(16.0, 16.0), metadata=at_least(0.0))
    lock_leakage: tuple[float, float] = field(default=(5e-4, 5e-4), metadata=at_least(0.0))
    lever_arm_area: tuple[float, float] = field(default=(1.5e-5, 1.5e-5), metadata=above(0.0))
    load_zero_code: tuple[float, float] = field(default=(2048.0, 2048.0), metadata=bounds(0.0, ADC_MAX))
    load_bar_per_code: tuple[float, float] = field(
        default=(25.0 / 2048.0, 25.0 / 2048.0), metadata=above(0.0)
    )
    supply_pressure: float = field(default=10.0, metadata=at_least(0.0))
    nominal_pressure: float = field(default=10.0, metadata=above(0.0))
    supply_low: float = field(default=5.0, metadata=at_least(0.0))
    bar_per_code: float = field(default=25.0 / 4095.0, metadata=above(0.0))
    adc_noise: float = field(default=2.0, metadata=at_least(0.0))
    ramp_ticks: int = field(default=1, metadata=at_least(1))
    seed: int = field(default=0, metadata=at_least(0))

    def __post_init__(self) -> None:
        check_bounds(self)
        if any(offset >= 1 << self.counter_bits for offset in self.zero_offset):
            raise ValueError(f"zero_offset must be below 2**counter_bits, got {self.zero_offset!r}")
        for name in ("direction", "valve_polarity"):
            if 0 in getattr(self, name):
                raise ValueError(f"{name} must be +1 or -1 per joint, got {getattr(self, name)!r}")


def check_lock_stability(settings: BenchSettings, plant: PlantConfig) -> None:
    """Rejects a lock too stiff or too damped for the plant's inertias at its tick (ValueError, with why).

    The smallest diagonal of the true mass matrix over the beta range is the inertia that must hold it.
    """
    params = plant.true_params
    limit = plant.joint_limits[1]
    inertia = min(
        float(min(mass_matrix([0.0, limit * index / (_INERTIA_SAMPLES - 1)], params).diagonal()))
        for index in range(_INERTIA_SAMPLES)
    )
    dt = plant.control_period
    for joint, (stiffness, damping) in enumerate(
        zip(settings.lock_stiffness, settings.lock_damping, strict=True)
    ):
        if math.sqrt(stiffness / inertia) * dt > _LOCK_OMEGA_DT_MAX:
            raise ValueError(
                f"lock_stiffness {settings.lock_stiffness!r}: joint {joint} rings at "
                f"{math.sqrt(stiffness / inertia):.0f} rad/s on an inertia of {inertia:.4g} kg m^2, too fast "
                f"for a {dt:g} s tick (at most {_LOCK_OMEGA_DT_MAX**2 * inertia / dt**2:.4g} N m/rad)"
            )
        if damping * dt / inertia > _LOCK_DAMPING_DT_MAX:
            raise ValueError(
                f"lock_damping {settings.lock_damping!r}: joint {joint} is over-damped for a {dt:g} s tick "
                f"on an inertia of {inertia:.4g} kg m^2 (at most {_LOCK_DAMPING_DT_MAX * inertia / dt:.4g})"
            )
