"""Argument handling of smm_dynamics: errors name the argument, mixed batch shapes, defaults, checks."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from smm_dynamics.parameters import BodyData
from smm_dynamics.validation import check_pair, check_scalar

import smm_dynamics as model
from smm_dynamics import SMMParameters

P = SMMParameters()
Q = np.array([0.3, -0.4])
QD = np.array([1.5, -0.7])
TAU = np.array([2.0, -1.0])

#: Every public array function and the names of its joint-array arguments, in call order.
SIGNATURES: list[tuple[Callable[..., Any], tuple[str, ...], tuple[Any, ...]]] = [
    (model.spin_angle, ("q",), ()),
    (model.spin_angle_gradient, ("q",), ()),
    (model.mass_matrix, ("q",), (P,)),
    (model.mass_matrix_inverse, ("q",), (P,)),
    (model.mass_matrix_gradient, ("q",), (P,)),
    (model.mass_matrix_time_derivative, ("q", "qd"), (P,)),
    (model.coriolis_matrix, ("q", "qd"), (P,)),
    (model.coriolis_vector, ("q", "qd"), (P,)),
    (model.potential_energy, ("q",), (P,)),
    (model.gravity_vector, ("q",), (P,)),
    (model.friction_torque, ("qd",), (P,)),
    (model.kinetic_energy, ("q", "qd"), (P,)),
    (model.total_energy, ("q", "qd"), (P,)),
    (model.forward_dynamics, ("q", "qd", "tau"), (P,)),
    (model.inverse_dynamics, ("q", "qd", "qdd"), (P,)),
    (model.end_effector_position, ("q",), (P,)),
    (model.rk4_step, ("q", "qd", "tau"), (1e-3, P)),
]
CASES = [
    pytest.param(function, names, rest, index, id=f"{function.__name__}-{names[index]}")
    for function, names, rest in SIGNATURES
    for index in range(len(names))
]


@pytest.mark.parametrize(("function", "names", "rest", "index"), CASES)
def test_a_wrong_shape_is_a_value_error_naming_the_argument(
    function: Callable[..., Any], names: tuple[str, ...], rest: tuple[Any, ...], index: int
) -> None:
    args: list[Any] = [Q, QD, TAU][: len(names)]
    args[index] = np.zeros(3)
    with pytest.raises(
        ValueError, match=rf"^{names[index]} must have shape \(2,\) or \(\.\.\., 2\), got shape \(3,\)"
    ):
        function(*args, *rest)


@pytest.mark.parametrize("function", [model.forward_dynamics, model.inverse_dynamics])
def test_a_wrong_disturbance_shape_names_tau_dist(function: Callable[..., Any]) -> None:
    with pytest.raises(ValueError, match=r"^tau_dist must have shape"):
        function(Q, QD, TAU, P, tau_dist=np.zeros(3))
    with pytest.raises(ValueError, match=r"^tau_dist must have shape"):
        model.rk4_step(Q, QD, TAU, 1e-3, P, tau_dist=np.zeros(1))


@pytest.mark.parametrize(("function", "names", "rest", "index"), CASES)
def test_non_numeric_input_is_a_value_error(
    function: Callable[..., Any], names: tuple[str, ...], rest: tuple[Any, ...], index: int
) -> None:
    args: list[Any] = [Q, QD, TAU][: len(names)]
    args[index] = ["a", "b"]
    with pytest.raises(ValueError):
        function(*args, *rest)


def _per_sample(function: Callable[..., Any], args: list[Any], n: int, **kwargs: Any) -> Any:
    """The function applied sample by sample (arguments of shape (n, 2) indexed, (2,) repeated)."""
    return np.stack(
        [function(*[a[k] if np.ndim(a) == 2 else a for a in args], P, **kwargs) for k in range(n)]
    )


BATCH = np.array([[0.1, 0.2], [-0.5, 0.9], [1.1, -0.3]])


@pytest.mark.parametrize(
    "function", [model.coriolis_matrix, model.coriolis_vector, model.mass_matrix_time_derivative]
)
@pytest.mark.parametrize("batched", [0, 1])
def test_one_batched_argument_broadcasts_against_a_single_sample(
    function: Callable[..., Any], batched: int
) -> None:
    args: list[Any] = [Q, QD]
    args[batched] = BATCH
    result = function(*args, P)
    assert result.shape[0] == 3
    np.testing.assert_allclose(result, _per_sample(function, args, 3), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("batched", [0, 1, 2, 3])
def test_inverse_dynamics_with_one_batched_argument(batched: int) -> None:
    args: list[Any] = [Q, QD, TAU, np.array([0.5, -0.25])]
    args[batched] = BATCH
    result = model.inverse_dynamics(args[0], args[1], args[2], P, tau_dist=args[3])
    assert result.shape == (3, 2)
    expected = np.stack(
        [
            model.inverse_dynamics(
                *[a[k] if a.ndim == 2 else a for a in args[:3]],
                P,
                tau_dist=(args[3][k] if args[3].ndim == 2 else args[3]),
            )
            for k in range(3)
        ]
    )
    np.testing.assert_allclose(result, expected, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("batched", [0, 1, 2])
def test_inverse_dynamics_batched_without_a_disturbance(batched: int) -> None:
    args: list[Any] = [Q, QD, TAU]
    args[batched] = BATCH
    result = model.inverse_dynamics(*args, P)
    np.testing.assert_allclose(result, _per_sample(model.inverse_dynamics, args, 3), rtol=1e-12, atol=1e-15)


def test_friction_is_on_by_default_and_adds_b_qd() -> None:
    default = model.forward_dynamics(Q, QD, TAU, P)
    np.testing.assert_array_equal(default, model.forward_dynamics(Q, QD, TAU, P, friction=True))
    without = model.forward_dynamics(Q, QD, TAU, P, friction=False)
    # M (qdd_without - qdd_with) = F = b qd
    np.testing.assert_allclose(
        model.mass_matrix(Q, P) @ (without - default), np.multiply(P.viscous_friction, QD), rtol=1e-12
    )
    state = (*Q.tolist(), *QD.tolist())
    floats = model.forward_dynamics_floats(state, (2.0, -1.0), P)  # type: ignore[arg-type]
    assert floats == model.forward_dynamics_floats(state, (2.0, -1.0), P, friction=True)  # type: ignore[arg-type]
    np.testing.assert_allclose(floats, default, rtol=1e-12)


def test_transverse_inertia_is_the_x_inertias_plus_the_parallel_axis_terms() -> None:
    bodies = (BodyData("a", 2.0, 0.1, (0.3, 0.7, 0.11)), BodyData("b", 1.0, 0.2, (0.05, 0.9, 0.13)))
    params = SMMParameters.from_table2(bodies)
    expected = 0.3 + 2.0 * 0.01 + 0.05 + 1.0 * 0.04  # Ixx + m l^2 summed; Iyy does not enter
    assert pytest.approx((expected,) * 3) == (params.I11, params.I22, params.I44)
    assert pytest.approx(0.11 + 0.13) == params.I55
    assert params.mass_lever == pytest.approx(2.0 * 0.1 + 1.0 * 0.2)


@pytest.mark.parametrize("name", ["I11", "I55", "mass_lever", "gravity", "link_length"])
@pytest.mark.parametrize("value", [math.nan, math.inf, True, "1.0", None])
def test_parameter_fields_must_be_finite_numbers(name: str, value: object) -> None:
    with pytest.raises(ValueError, match=rf"^{name} must be a finite number, got {value!r}"):
        SMMParameters(**{name: value})  # type: ignore[arg-type]


def test_viscous_friction_errors_name_the_field() -> None:
    with pytest.raises(ValueError, match=r"^viscous_friction must be >= 0"):
        SMMParameters(viscous_friction=(0.1, -0.1))


def test_inertia_scale_accepts_any_positive_factor_and_names_a_bad_one() -> None:
    half = P.with_inertia_scale(0.5)
    assert pytest.approx((P.I11 / 2, P.I22 / 2, P.I44 / 2, P.I55 / 2)) == (
        half.I11,
        half.I22,
        half.I44,
        half.I55,
    )
    assert half.mass_lever == P.mass_lever
    with pytest.raises(ValueError, match=r"^factor must be > 0"):
        P.with_inertia_scale(0.0)
    for bad in (math.nan, True, "2"):
        with pytest.raises(ValueError, match=r"^factor must be a finite number"):
            P.with_inertia_scale(bad)  # type: ignore[arg-type]


def test_a_scalar_without_a_sign_rule_may_be_negative() -> None:
    check_scalar("t", -1.0)
    check_pair("offset", (-1.0, -2.0))
    with pytest.raises(ValueError, match=r"^t must be >= 0, got -1.0"):
        check_scalar("t", -1.0, non_negative=True)
