"""SimulatedPlant input checks and reset state (pure): each error names its argument, the stops are inside."""

from __future__ import annotations

import math

import numpy as np
import pytest
from smm_sim.plant import PlantConfig, SimulatedPlant


@pytest.mark.parametrize("command", [("x", 1.0), (1.0, "x"), ["a", "b"], (1j, 0.0)])
def test_a_non_numeric_command_is_a_value_error_naming_tau_command(command: object) -> None:
    plant = SimulatedPlant(PlantConfig())
    with pytest.raises(ValueError, match=r"^tau_command must be numeric, shape \(2,\)"):
        plant.step(command, 1e-3)  # type: ignore[arg-type]
    assert plant.time_ns == 0


@pytest.mark.parametrize("dt", [0.0, 4e-10, -1e-3])
def test_a_step_shorter_than_one_nanosecond_is_refused(dt: float) -> None:
    with pytest.raises(ValueError, match=r"^dt must be >= 1 ns"):
        SimulatedPlant(PlantConfig()).step((0.0, 0.0), dt)


def test_a_step_of_one_nanosecond_is_accepted() -> None:
    plant = SimulatedPlant(PlantConfig())
    plant.step((1.0, -1.0), 1e-9)
    assert plant.time_ns == 1


@pytest.mark.parametrize("dt", [True, "0.001", None, math.nan, math.inf])
def test_dt_must_be_a_finite_number(dt: object) -> None:
    with pytest.raises(ValueError, match=r"^dt must be a finite number of seconds"):
        SimulatedPlant(PlantConfig()).step((0.0, 0.0), dt)  # type: ignore[arg-type]


def test_reset_exactly_on_the_stops_is_inside_the_range() -> None:
    plant = SimulatedPlant(PlantConfig(joint_limits=(1.2, 1.3)))
    plant.reset((1.2, -1.3))
    assert plant.state_floats == (1.2, -1.3, 0.0, 0.0)
    with pytest.raises(ValueError, match=r"^position must lie within joint_limits"):
        plant.reset((1.2, 1.31))
    with pytest.raises(ValueError):
        plant.reset(("a", "b"))  # type: ignore[arg-type]


def test_reset_clears_the_command_in_the_internals() -> None:
    plant = SimulatedPlant(PlantConfig(torque_limit=(5.0, 5.0)))
    plant.step((7.0, -3.0), 1e-3)
    np.testing.assert_array_equal(plant.internals["commanded_torque"], [7.0, -3.0])
    np.testing.assert_array_equal(plant.internals["saturated_torque"], [5.0, -3.0])
    plant.reset()
    for key in ("commanded_torque", "saturated_torque", "valve_torque", "applied_torque"):
        np.testing.assert_array_equal(plant.internals[key], [0.0, 0.0])


def test_without_valve_lag_the_valve_torque_is_the_saturated_command_per_joint() -> None:
    plant = SimulatedPlant(PlantConfig(torque_limit=(5.0, 5.0)))
    plant.step((7.0, -3.0), 1e-3)
    np.testing.assert_array_equal(plant.internals["valve_torque"], [5.0, -3.0])
    np.testing.assert_array_equal(plant.internals["applied_torque"], [5.0, -3.0])


@pytest.mark.parametrize("scale", [1.0, 1e-170])
def test_the_valve_opens_with_t_rise_and_closes_with_t_fall_at_any_torque_scale(scale: float) -> None:
    """First-order lag of the module docstring, by hand; at 1e-170 N m (goal - start) * start underflows."""
    rise, fall, dt = 0.004, 0.010, 1e-3
    plant = SimulatedPlant(PlantConfig(valve_time_constants=(rise, fall)))
    c1, c2, c3 = 1.0 * scale, 3.0 * scale, -2.0 * scale
    plant.step((c1, -c1), dt)
    v1 = c1 * (1.0 - math.exp(-dt / rise))  # opening from 0
    np.testing.assert_allclose(plant.internals["valve_torque"], [v1, -v1], rtol=1e-12)
    plant.step((c2, -c2), dt)
    v2 = c2 + (v1 - c2) * math.exp(-dt / rise)  # |tau| grows: opening
    np.testing.assert_allclose(plant.internals["valve_torque"], [v2, -v2], rtol=1e-12)
    plant.step((c3, -c3), dt)
    v3 = c3 + (v2 - c3) * math.exp(-dt / fall)  # moves towards 0: closing
    np.testing.assert_allclose(plant.internals["valve_torque"], [v3, -v3], rtol=1e-12)


@pytest.mark.parametrize(
    ("quantum", "expected"),
    [((1.0, 0.0), [2.0, 2.6]), ((0.0, 1.0), [2.4, 3.0]), ((0.5, 0.0), [2.5, 2.6]), ((0.0, 0.0), [2.4, 2.6])],
)
def test_a_zero_quantum_leaves_its_joint_unquantised(
    quantum: tuple[float, float], expected: list[float]
) -> None:
    plant = SimulatedPlant(PlantConfig(torque_quantum=quantum))
    plant.step((2.4, 2.6), 1e-3)
    np.testing.assert_allclose(plant.internals["valve_torque"], expected, rtol=1e-15)
