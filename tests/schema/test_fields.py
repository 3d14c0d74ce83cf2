"""Generic config dataclass <-> parameter mapping of smm_schema.fields."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import pytest
from smm_controller.baselines import FPDConfig, NPDConfig, PIDConfig
from smm_controller.fleso import FLESOConfig
from smm_controller.fpdeso import FPDESOConfig
from smm_controller.fuzzy_pd import FuzzyPDConfig
from smm_controller.reference import RampHoldReference, SineReference, StepReference
from smm_controller.td import TrackingDifferentiatorConfig
from smm_schema.fields import (
    FieldKind,
    config_fields,
    config_from_parameters,
    config_to_parameters,
    docstring_attributes,
    parameter_name,
)

from smm_dynamics import SMMParameters

ALL_CONFIGS = [
    TrackingDifferentiatorConfig(),
    FLESOConfig(),
    FPDESOConfig(),
    FPDConfig(),
    PIDConfig(),
    NPDConfig(),
    SMMParameters(),
    StepReference(),
    SineReference(),
    RampHoldReference(),
]


@dataclass(frozen=True)
class Inner:
    """Inner block.

    Attributes:
        gain: A gain (1/s), per joint,
            continued on a second line.
        count: How many.
    """

    gain: tuple[float, float] = (1.0, 2.0)
    count: int = 3

    def __post_init__(self) -> None:
        if min(self.gain) <= 0.0:
            raise ValueError(f"gain must be > 0, got {self.gain!r}")


@dataclass(frozen=True)
class Outer:
    """Outer block.

    Attributes:
        inner: Nested settings.
        name: A label.
        mode: One of two modes.
        enabled: On or off.
        scale: A scalar (m).
        values: Any number of values.
    """

    inner: Inner = Inner()
    name: str = "x"
    mode: Literal["fast", "slow"] = "fast"
    enabled: bool = True
    scale: float = 0.5
    values: tuple[float, ...] = (1.0,)
    derived: float = field(init=False, default=0.0)


def test_fields_are_flattened_with_dotted_names_kinds_lengths_and_docstring_descriptions() -> None:
    fields = {f.name: f for f in config_fields(Outer)}
    assert list(fields) == ["inner.gain", "inner.count", "name", "mode", "enabled", "scale", "values"]
    assert fields["inner.gain"].path == ("inner", "gain")
    assert fields["inner.gain"].kind is FieldKind.DOUBLE_ARRAY and fields["inner.gain"].length == 2
    assert fields["inner.count"].kind is FieldKind.INTEGER
    assert fields["mode"].kind is FieldKind.STRING
    assert fields["enabled"].kind is FieldKind.BOOL
    assert fields["scale"].kind is FieldKind.DOUBLE and fields["scale"].length is None
    assert fields["values"].kind is FieldKind.DOUBLE_ARRAY and fields["values"].length is None
    assert fields["inner.gain"].description == "A gain (1/s), per joint, continued on a second line."
    assert fields["scale"].description == "A scalar (m)."


def test_docstring_attributes_stop_at_the_next_section() -> None:
    @dataclass
    class Documented:
        """Summary.

        Attributes:
            a: First.
            b: Second.

        Raises:
            c: Not an attribute.
        """

    assert docstring_attributes(Documented) == {"a": "First.", "b": "Second."}


def test_unsupported_field_type_is_refused_naming_the_field() -> None:
    @dataclass(frozen=True)
    class Bad:
        mapping: dict[str, float]

    with pytest.raises(TypeError, match="mapping"):
        config_fields(Bad)


@pytest.mark.parametrize("config", ALL_CONFIGS, ids=lambda c: type(c).__name__)
def test_every_config_of_the_stack_round_trips_through_parameter_values(config: Any) -> None:
    values = config_to_parameters(config, prefix="p")
    assert all(name.startswith("p.") for name in values)
    assert all(not isinstance(v, tuple) for v in values.values())  # arrays go out as lists
    rebuilt = config_from_parameters(type(config), type(config)(), values, prefix="p")
    assert rebuilt == config


def test_nested_override_builds_a_new_config_and_keeps_the_rest() -> None:
    current = FPDESOConfig()
    new = config_from_parameters(FPDESOConfig, current, {"fpdeso.fuzzy.k_e": [3.0, 4.0]}, prefix="fpdeso")
    assert new.fuzzy.k_e == (3.0, 4.0)
    assert new.fuzzy.kp0 == current.fuzzy.kp0
    assert new.robust_gain == current.robust_gain
    assert current.fuzzy.k_e == (2.0, 6.0)  # the old config is untouched


def test_names_outside_the_prefix_or_unknown_are_ignored() -> None:
    current = FLESOConfig()
    new = config_from_parameters(
        FLESOConfig, current, {"other.w0": [1.0, 1.0], "fleso.nope": 3}, prefix="fleso"
    )
    assert new is current


def test_integers_are_accepted_for_doubles() -> None:
    new = config_from_parameters(FLESOConfig, FLESOConfig(), {"w0": [30, 40]})
    assert new.w0 == (30.0, 40.0) and all(isinstance(v, float) for v in new.w0)


def test_infinity_reaches_the_dataclass_which_decides() -> None:
    new = config_from_parameters(PIDConfig, PIDConfig(), {"integrator_limit": [math.inf, 5.0]})
    assert new.integrator_limit == (math.inf, 5.0)
    with pytest.raises(ValueError, match="kp"):
        config_from_parameters(PIDConfig, PIDConfig(), {"kp": [math.inf, 1.0]})


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"fuzzy.k_e": [1.0, 2.0, 3.0]}, r"fuzzy\.k_e must have 2 values \(alpha, beta\), got 3"),
        ({"fuzzy.k_e": [1.0]}, r"fuzzy\.k_e must have 2 values"),
        ({"fuzzy.k_e": "1.0"}, r"fuzzy\.k_e must be an array"),
        ({"fuzzy.k_e": [1.0, "x"]}, r"fuzzy\.k_e\[1\] must be a number"),
        ({"fuzzy.grid_points": 3.5}, r"fuzzy\.grid_points must be an integer"),
        ({"fuzzy.grid_points": True}, r"fuzzy\.grid_points must be an integer"),
        ({"fuzzy.kp0": [-1.0, 4150.0]}, r"kp0 must be > 0"),
        ({"fuzzy.k1": [5000.0, 13.0]}, r"k1 must be < kp0"),
        ({"robust_gain": [-0.1, 0.1]}, r"robust_gain must be >= 0"),
    ],
)
def test_bad_values_are_refused_with_a_message_naming_the_field(
    overrides: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        config_from_parameters(FPDESOConfig, FPDESOConfig(), overrides)


def test_wrong_current_type_is_a_programming_error() -> None:
    with pytest.raises(TypeError, match="FLESOConfig"):
        config_from_parameters(FLESOConfig, PIDConfig(), {})  # type: ignore[arg-type]


def test_parameter_name_joins_prefix_and_field() -> None:
    assert parameter_name("", "w0") == "w0"
    assert parameter_name("fpdeso", "fuzzy.k_e") == "fpdeso.fuzzy.k_e"


def test_fuzzy_config_descriptions_come_from_its_docstring() -> None:
    fields = {f.name: f for f in config_fields(FuzzyPDConfig)}
    assert "1/rad" in fields["k_e"].description
