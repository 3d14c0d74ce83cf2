"""The bench's servo valves and actuators, one tick at a time: torque outside the overlap, lock inside (pure).

Open, a valve's torque follows its spool through the first-order lag (today's torque model, with polarity,
null bias, overlap and a gain per direction); inside the overlap, disabled or in its fail-safe position, the
trapped oil holds the joint: a spring of ``lock_stiffness`` with ``lock_damping``, whose load relaxes through
the leakage. docs/BENCH.md, "The valve".
"""

from __future__ import annotations

import math

from smm_dynamics.valve import valve_lag_step
from smm_hw_bridge.pressure import PASCAL_PER_BAR
from smm_hw_bridge.protocol import CODE_MAX
from smm_sim.plant import SimulatedPlant

from smm_bench_emulator.bench import BenchSettings

__all__ = ["HydraulicValves"]


class HydraulicValves:
    """Both joints' valve and actuator: the torque each gives over a tick, and the load pressure behind it.

    Args:
        settings: The bench's valve and actuator truths.
        lag: (T_rise, T_fall) of the valves' first-order lag (s), or None for none.
    """

    def __init__(self, settings: BenchSettings, lag: tuple[float, float] | None) -> None:
        self._settings = settings
        self._lag = lag
        self.reset()

    def reset(self) -> None:
        """Valves at null, oil unloaded."""
        self._torque = [0.0, 0.0]
        self._held = [0.0, 0.0]
        self.locked = (True, True)
        """Per joint, True while the trapped oil holds the joint (the last tick)."""
        self.applied = (0.0, 0.0)
        """Torque the actuators gave over the last tick (N m)."""

    def target(self, codes: tuple[int, int], supply: float) -> tuple[float, float]:
        """Torque the valves head for with ``codes`` on the D/A and ``supply`` bar, before the lag (N m).

        The gain per direction included; :meth:`drive` lags the spool, then applies the gain.
        """
        settings = self._settings
        scale = math.sqrt(max(supply, 0.0) / settings.nominal_pressure)
        torque = []
        for joint, code in enumerate(codes):
            spool = code - settings.valve_null_bias[joint]
            opening = math.copysign(max(abs(spool) - settings.valve_deadband[joint], 0.0), spool)
            value = opening / CODE_MAX * settings.full_scale_torque[joint] * scale
            value *= settings.valve_polarity[joint]
            torque.append(value * self._gain(joint, value))
        return torque[0], torque[1]

    def _gain(self, joint: int, torque: float) -> float:
        """The actuator's gain for a torque of this sign (the direction it drives q)."""
        settings = self._settings
        return (settings.valve_gain_positive if torque > 0.0 else settings.valve_gain_negative)[joint]

    def move(self, plant: SimulatedPlant, codes: tuple[int, int], enabled: bool, supply: float) -> None:
        """Moves ``plant`` (built without a valve lag) over one of its control periods with these valves.

        Args:
            plant: The joints the actuators drive.
            codes: D/A codes on the valves.
            enabled: False when the valves are disabled (fail-safe position).
            supply: Supply pressure (bar).
        """
        h = plant.config.period_ns / 1_000_000_000
        before = plant.state_floats
        plant.step(self.drive(codes, enabled, supply, h), plant.config.control_period)
        after = plant.state_floats
        change = tuple(a - b for a, b in zip(after, before, strict=True))
        self.follow((change[0], change[1]), (change[2], change[3]), h)

    def drive(self, codes: tuple[int, int], enabled: bool, supply: float, h: float) -> tuple[float, float]:
        """The torque each actuator gives over the next ``h`` s (N m), held by the oil or driven by the valve.

        Args:
            codes: D/A codes on the valves.
            enabled: False when the board has the valves disabled (fail-safe position: the oil is trapped).
            supply: Supply pressure (bar).
            h: Tick (s), > 0.
        """
        settings = self._settings
        target = self.target(codes, supply)
        locked, applied = [], []
        for joint in range(2):
            spool = codes[joint] - settings.valve_null_bias[joint]
            holds = not enabled or abs(spool) < settings.valve_deadband[joint]
            if holds:
                if not self.locked[joint]:
                    self._held[joint] = self._torque[joint]  # the oil is trapped at the pressure it had
                self._torque[joint] = mean = self._held[joint]
            else:  # the spool lags, the actuator's gain for the direction it drives applies after it
                goal, start = target[joint], self._torque[joint]
                goal /= self._gain(joint, goal)
                start /= self._gain(joint, start)
                end, mean = self._lagged(start, goal, h)
                self._torque[joint] = end * self._gain(joint, end)
                mean *= self._gain(joint, mean)
            locked.append(holds)
            applied.append(mean)
        self.locked = (locked[0], locked[1])
        self.applied = (applied[0], applied[1])
        return self.applied

    def _lagged(self, start: float, goal: float, h: float) -> tuple[float, float]:
        """The valve lag's value after ``h`` s towards ``goal`` and its mean (the goal without a lag)."""
        if self._lag is None:
            return goal, goal
        return valve_lag_step(start, goal, h, self._lag[0], self._lag[1])

    def follow(self, moved: tuple[float, float], accelerated: tuple[float, float], h: float) -> None:
        """After a tick in which a joint moved ``moved`` rad and changed speed by ``accelerated`` rad/s.

        A held joint's oil resists as a spring and a damper on the change since it was trapped, so the
        torque never jumps; the leakage relaxes the load it holds.
        """
        settings = self._settings
        for joint in range(2):
            if self.locked[joint]:
                stiffness = settings.lock_stiffness[joint]
                held = self._held[joint]
                leak = stiffness * settings.lock_leakage[joint] * h
                squeeze = stiffness * moved[joint] + settings.lock_damping[joint] * accelerated[joint]
                self._held[joint] = held - squeeze - held * leak

    def load_pressure(self) -> tuple[float, float]:
        """Chamber-pressure difference behind the torque of the last tick (bar)."""
        settings = self._settings
        return (
            self.applied[0] / settings.lever_arm_area[0] / PASCAL_PER_BAR,
            self.applied[1] / settings.lever_arm_area[1] / PASCAL_PER_BAR,
        )
