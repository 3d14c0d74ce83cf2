"""The derived Christoffel C against the C11, C12 printed in the paper's Appendix A.

Outcome (also in docs/DYNAMICS.md): the printed first row does not belong to the printed M. It agrees with
the Christoffel form only for C11 on the line alpha = 0; elsewhere both the entries and (C q')_1 differ,
and the printed C11 breaks the skew-symmetry of dM/dt - 2C, which any valid C of the printed M keeps.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.typing import NDArray

from smm_dynamics import SMMParameters, coriolis_matrix, coriolis_vector, mass_matrix_time_derivative

PARAMS = SMMParameters()
angles = st.floats(-1.2, 1.2, allow_nan=False, allow_subnormal=True)
rates = st.floats(-3.0, 3.0, allow_nan=False, allow_subnormal=True)


def printed_first_row(
    q: NDArray[np.float64], qd: NDArray[np.float64], p: SMMParameters
) -> NDArray[np.float64]:
    """C11, C12 typed in literally from Appendix A."""
    (alpha, beta), (alpha_dot, beta_dot) = q, qd
    sa, ca, ta, sec = np.sin(alpha), np.cos(alpha), np.tan(alpha), 1.0 / np.cos(alpha)
    sb, cb = np.sin(beta), np.cos(beta)
    d = ta**2 + cb**2
    c11 = (
        sec**5
        * cb
        * d**-3
        * (
            2 * sa * cb * (p.I11 * ca**2 * sb**2 - p.I55 * ta**2) * alpha_dot
            + ca * sb * (2 * p.I11 * sa**2 - p.I55 * ta**2 + p.I55 * cb**2) * beta_dot
        )
    )
    c12 = (
        sec**2
        * d**-3
        * (
            sb * cb * (2 * p.I55 * ta**2 - 0.5 * p.I11 * cb**2) * alpha_dot
            + ta * cb**2 * (p.I55 * sec**2 - 0.5 * p.I11) * beta_dot
        )
    )
    return np.array([c11, c12])


@given(angles, rates, rates)
def test_printed_c11_agrees_on_the_line_alpha_zero(beta: float, alpha_dot: float, beta_dot: float) -> None:
    q, qd = np.array([0.0, beta]), np.array([alpha_dot, beta_dot])
    derived = coriolis_matrix(q, qd, PARAMS)[0, 0]
    # Both reduce to I55 sin(beta) / cos^3(beta) * beta_dot there.
    expected = PARAMS.I55 * np.sin(beta) / np.cos(beta) ** 3 * beta_dot
    np.testing.assert_allclose(derived, expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(printed_first_row(q, qd, PARAMS)[0], expected, rtol=1e-12, atol=1e-15)


@given(angles, rates)
def test_printed_c12_differs_on_the_line_alpha_zero(beta: float, alpha_dot: float) -> None:
    q, qd = np.array([0.0, beta]), np.array([alpha_dot, 0.0])
    factor = np.sin(beta) / np.cos(beta) ** 3 * alpha_dot
    np.testing.assert_allclose(coriolis_matrix(q, qd, PARAMS)[0, 1], PARAMS.I55 * factor, atol=1e-15)
    np.testing.assert_allclose(printed_first_row(q, qd, PARAMS)[1], -0.5 * PARAMS.I11 * factor, atol=1e-15)


@given(angles, rates)
def test_on_beta_zero_only_the_printed_c_has_an_alpha_torque(alpha: float, alpha_dot: float) -> None:
    # On beta = 0, M = diag(I44 - I11 + I55, I22) for every alpha, so dM/dalpha = 0 and any valid C
    # gives (C q')_1 = 0 when beta_dot = 0. The printed C11 gives -2 I55 sin^3(alpha)/cos(alpha) alpha_dot^2.
    q, qd = np.array([alpha, 0.0]), np.array([alpha_dot, 0.0])
    np.testing.assert_allclose(coriolis_vector(q, qd, PARAMS)[0], 0.0, atol=1e-15)
    printed = printed_first_row(q, qd, PARAMS) @ qd
    expected = -2.0 * PARAMS.I55 * np.sin(alpha) ** 3 / np.cos(alpha) * alpha_dot**2
    np.testing.assert_allclose(printed, expected, rtol=1e-12, atol=1e-15)


def test_printed_c11_breaks_skew_symmetry_where_the_derived_keeps_it() -> None:
    # Skew-symmetry of N = dM/dt - 2C needs N11 = 0; the measured values are in docs/DYNAMICS.md.
    q, qd = np.array([0.5, 0.3]), np.array([1.0, 1.0])
    dm11 = mass_matrix_time_derivative(q, qd, PARAMS)[0, 0]
    assert abs(dm11 - 2.0 * coriolis_matrix(q, qd, PARAMS)[0, 0]) < 1e-15
    assert dm11 - 2.0 * printed_first_row(q, qd, PARAMS)[0] == pytest.approx(0.018178, rel=1e-4)


def test_derived_and_printed_first_rows_at_the_documented_point() -> None:
    q, qd = np.array([0.5, 0.3]), np.array([1.0, 1.0])
    np.testing.assert_allclose(coriolis_matrix(q, qd, PARAMS)[0], [0.013641, 0.037773], rtol=1e-4)
    np.testing.assert_allclose(printed_first_row(q, qd, PARAMS), [0.004552, 0.023227], rtol=1e-4)


def test_printed_coriolis_torque_differs_over_the_workspace() -> None:
    grid = np.linspace(-1.2, 1.2, 25)
    rng = np.random.default_rng(0)
    relative = []
    for alpha in grid:
        for beta in grid:
            q, qd = np.array([alpha, beta]), rng.uniform(-1.0, 1.0, 2)
            derived = coriolis_vector(q, qd, PARAMS)
            printed = printed_first_row(q, qd, PARAMS) @ qd
            relative.append(abs(derived[0] - printed) / max(np.abs(derived).max(), 1e-12))
    assert np.median(relative) > 0.5
