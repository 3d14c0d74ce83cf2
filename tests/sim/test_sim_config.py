"""smm_sim.config: the plant mirror, the run config, their validation and the default parameter file."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
import yaml
from smm_schema.fields import config_fields, config_to_parameters
from smm_sim.plant import PlantConfig

from smm_dynamics import SMMParameters
from smm_sim.config import MAX_COMMAND_TIMEOUT, PlantParameters, SimNodeConfig

CONFIG_DIR = Path(__file__).resolve().parents[2] / "src" / "smm_sim" / "config"


def test_every_plant_config_field_is_a_parameter() -> None:
    mirrored = {field.name for field in dataclasses.fields(PlantParameters) if field.init}
    plant_fields = {field.name for field in dataclasses.fields(PlantConfig)}
    assert plant_fields <= mirrored
    assert mirrored - plant_fields == {"initial_position"}


def test_defaults_give_the_default_plant_config() -> None:
    assert PlantParameters().plant_config == PlantConfig()


def test_zero_encodings_mean_off_and_values_pass_through() -> None:
    off = PlantParameters()
    assert off.plant_config.torque_limit == (math.inf, math.inf)
    assert off.plant_config.valve_time_constants is None
    on = PlantParameters(
        torque_limit=(3.0, 2.0), valve_time_constants=(0.02, 0.01), inertia_scale=1.1, seed=7
    )
    assert on.plant_config.torque_limit == (3.0, 2.0)
    assert on.plant_config.valve_time_constants == (0.02, 0.01)
    assert on.plant_config.true_params == SMMParameters().with_inertia_scale(1.1)
    assert on.plant_config.seed == 7


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"valve_time_constants": (0.02, 0.0)}, "valve_time_constants"),
        ({"torque_limit": (1.0,)}, "torque_limit"),
        ({"initial_position": (0.0, 1.31)}, "initial_position"),
        ({"inertia_scale": 0.0}, "inertia_scale"),
        ({"control_period": 0.0}, "control_period"),
    ],
)
def test_invalid_plant_parameters_name_the_field(changes: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        PlantParameters(**changes)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"clock_mode": "wall"}, "clock_mode"),
        ({"command_timeout": 0.0}, "command_timeout"),
        ({"republish_period": math.inf}, "republish_period"),
        ({"max_steps": -1}, "max_steps"),
        ({"duration": -1.0}, "duration"),
        ({"stats_period": math.nan}, "stats_period"),
    ],
)
def test_invalid_node_config_names_the_field(changes: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        SimNodeConfig(**changes)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("max_steps", "duration", "expected"),
    [(0, 0.0, None), (7, 0.0, 7), (0, 5.0, 5000), (7, 5.0, 7), (9000, 5.0, 5000), (0, 0.0004, 1)],
)
def test_step_limit_is_the_earlier_of_max_steps_and_duration(
    max_steps: int, duration: float, expected: int | None
) -> None:
    assert SimNodeConfig(max_steps=max_steps, duration=duration).step_limit(1_000_000) == expected


def test_default_parameter_file_matches_the_dataclass_defaults() -> None:
    content = yaml.safe_load((CONFIG_DIR / "smm_sim.yaml").read_text())
    values = content["/**/smm_sim_node"]["ros__parameters"]
    expected = {**config_to_parameters(PlantParameters()), **config_to_parameters(SimNodeConfig())}
    listed = {name for name in expected if not name.startswith("params.")}
    assert set(values) == listed
    for name in listed:
        assert values[name] == expected[name], name
        # A double parameter must be written as a float, or ROS types it as an integer and refuses it.
        assert type(values[name]) is type(expected[name]), name


def test_every_parameter_has_a_description() -> None:
    for config in (PlantParameters, SimNodeConfig):
        for field in config_fields(config):
            assert field.description, f"{config.__name__}.{field.name} has no description"


def test_command_timeout_is_bounded_to_what_still_protects_the_plant() -> None:
    assert SimNodeConfig(command_timeout=MAX_COMMAND_TIMEOUT).command_timeout == MAX_COMMAND_TIMEOUT
    with pytest.raises(ValueError, match="command_timeout"):
        SimNodeConfig(command_timeout=1e9)
