"""SMMParameters: the Table 2 mapping, validation and the case2 inertia scaling."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from smm_dynamics import TABLE2_BODIES, BodyData, SMMParameters

# Table 2 of the paper, typed in again here (lengths in mm) so that the mapping is checked against the source.
RUDDER = (3.9, 5.0, (0.027, 0.027, 0.005))
SPIN_MOTOR = (1.2, 3.5, (0.01, 0.01, 0.01))
ROTOR = (5.4, 3.0, (0.032, 0.032, 0.056))


def test_table2_bodies_transcribe_the_paper() -> None:
    for body, (mass, length_mm, inertia) in zip(TABLE2_BODIES, (RUDDER, SPIN_MOTOR, ROTOR), strict=True):
        assert body.mass == mass
        assert body.length == pytest.approx(length_mm * 1e-3, rel=1e-15)
        assert body.inertia == inertia


def test_transverse_inertias_are_x_inertias_plus_parallel_axis_terms() -> None:
    params = SMMParameters.from_table2()
    parallel_axis = sum(mass * (length_mm * 1e-3) ** 2 for mass, length_mm, _ in (RUDDER, SPIN_MOTOR, ROTOR))
    expected = 0.032 + 0.01 + 0.027 + parallel_axis
    for name in ("I11", "I22", "I44"):
        assert getattr(params, name) == pytest.approx(expected, rel=1e-14)
    assert parallel_axis == pytest.approx(1.608e-4, rel=1e-12)


def test_axial_inertia_and_mass_lever_follow_table2() -> None:
    params = SMMParameters.from_table2()
    np.testing.assert_allclose(params.I55, 0.056 + 0.01 + 0.005, rtol=1e-14)
    assert params.mass_lever == pytest.approx(3.9 * 0.005 + 1.2 * 0.0035 + 5.4 * 0.003, rel=1e-14)
    assert params.mass_lever == pytest.approx(0.0399, rel=1e-12)


def test_defaults_are_the_table2_parameters() -> None:
    defaults = SMMParameters()
    assert defaults == SMMParameters.from_table2()
    assert defaults.gravity == 9.81
    assert defaults.gravity_sign == 1.0
    assert defaults.viscous_friction == (0.1, 0.1)
    assert defaults.link_length == 0.1


def test_from_table2_uses_the_given_bodies_and_overrides() -> None:
    single = (BodyData("disc", 2.0, 0.1, (0.5, 0.5, 0.25)),)
    params = SMMParameters.from_table2(single, link_length=0.2, gravity_sign=-1.0)
    np.testing.assert_allclose(params.I11, 0.5 + 2.0 * 0.01, rtol=1e-14)
    np.testing.assert_allclose(params.I55, 0.25, rtol=1e-14)
    assert params.mass_lever == pytest.approx(0.2)
    assert params.link_length == 0.2
    assert params.gravity_sign == -1.0


def test_with_inertia_scale_scales_the_four_inertias_only() -> None:
    nominal = SMMParameters()
    scaled = nominal.with_inertia_scale(1.1)
    for name in ("I11", "I22", "I44", "I55"):
        assert getattr(scaled, name) == pytest.approx(1.1 * getattr(nominal, name), rel=1e-15)
    unchanged = ("mass_lever", "gravity", "gravity_sign", "viscous_friction", "link_length")
    for name in unchanged:
        assert getattr(scaled, name) == getattr(nominal, name)


@pytest.mark.parametrize("factor", [0.0, -1.1, math.nan, math.inf])
def test_with_inertia_scale_rejects_bad_factors(factor: float) -> None:
    with pytest.raises(ValueError, match="factor"):
        SMMParameters().with_inertia_scale(factor)


def test_parameters_are_frozen() -> None:
    params = SMMParameters()
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.I11 = 1.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("I11", 0.0),
        ("I11", -0.1),
        ("I22", 0.0),
        ("I22", math.nan),
        ("I44", -1e-3),
        ("I44", math.inf),
        ("I55", 0.0),
        ("I55", -0.071),
        ("mass_lever", -0.01),
        ("mass_lever", math.nan),
        ("gravity", -9.81),
        ("gravity", math.inf),
        ("gravity_sign", 0.0),
        ("gravity_sign", 0.5),
        ("gravity_sign", math.nan),
        ("viscous_friction", (-0.1, 0.1)),
        ("viscous_friction", (0.1, math.nan)),
        ("viscous_friction", (0.1,)),
        ("viscous_friction", [0.1, 0.1]),
        ("link_length", 0.0),
        ("link_length", -0.1),
        ("link_length", math.inf),
    ],
)
def test_invalid_parameters_are_rejected_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        SMMParameters(**{field: value})  # type: ignore[arg-type]


def test_limits_of_validation_are_inclusive_where_documented() -> None:
    params = SMMParameters(mass_lever=0.0, gravity=0.0, gravity_sign=-1.0, viscous_friction=(0.0, 0.0))
    assert params.mass_lever == 0.0
    assert params.viscous_friction == (0.0, 0.0)
