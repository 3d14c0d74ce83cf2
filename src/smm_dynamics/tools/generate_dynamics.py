#!/usr/bin/env python3
"""Generates ``smm_dynamics/_generated.py`` from the inertia matrix printed in the paper's Appendix A.

The Coriolis matrix of the paper is cut off after C21, so it is derived here, exactly, from the printed
M(q) by Christoffel symbols of the first kind (SPEC section 1):

    C_kj = sum_i c_ijk qdot_i,  c_ijk = 0.5 (dM_kj/dq_i + dM_ki/dq_j - dM_ij/dq_k),

which makes dM/dt - 2C skew-symmetric. All derivatives are symbolic (sympy). The emitted functions
take sin/cos of alpha and beta instead of the angles, contain arithmetic only, and so work unchanged
on Python floats (fast single-sample path) and on numpy arrays (batch path).

Usage: ``python tools/generate_dynamics.py [--output PATH]`` (default: the package's ``_generated.py``).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import sympy as sp

ALPHA, BETA = sp.symbols("alpha beta", real=True)
ALPHA_DOT, BETA_DOT = sp.symbols("alpha_dot beta_dot", real=True)
I11, I22, I44, I55 = sp.symbols("I11 I22 I44 I55", positive=True)
SA, CA, SB, CB = sp.symbols("sa ca sb cb", real=True)
# D = tan^2(alpha) + cos^2(beta) of Appendix A, times cos^2(alpha):
D_SCALED = sp.Symbol("d_scaled", positive=True)

COORDINATES = (ALPHA, BETA)
VELOCITIES = (ALPHA_DOT, BETA_DOT)

DEFAULT_OUTPUT = Path(__file__).resolve().parent.parent / "smm_dynamics" / "_generated.py"


def printed_mass_matrix() -> sp.Matrix:
    """M(q) transcribed from Appendix A of the paper (tan/sec form)."""
    d = sp.tan(ALPHA) ** 2 + sp.cos(BETA) ** 2
    sec_a = sp.sec(ALPHA)
    m11 = I44 + sec_a**2 * sp.cos(BETA) ** 2 * d**-2 * (I55 * sec_a**2 - I11 * d)
    m12 = sp.tan(ALPHA) * sp.sin(BETA) * sp.cos(BETA) * d**-2 * (I55 * sec_a**2 - sp.Rational(1, 2) * I11 * d)
    m22 = I22 + I55 * sp.tan(ALPHA) ** 2 * sp.sin(BETA) ** 2 * d**-2
    return sp.Matrix([[m11, m12], [m12, m22]])


def spin_angle() -> sp.Expr:
    """Spin angle theta(alpha, beta) = atan2(tan(alpha), cos(beta)) (SPEC section 1)."""
    return sp.atan2(sp.tan(ALPHA), sp.cos(BETA))


def to_sin_cos(expr: sp.Expr) -> sp.Expr:
    """Rewrites an expression in alpha, beta as a rational function of sa, ca, sb, cb."""
    expr = expr.subs({sp.tan(ALPHA): sp.sin(ALPHA) / sp.cos(ALPHA), sp.sec(ALPHA): 1 / sp.cos(ALPHA)})
    expr = expr.subs({sp.sin(ALPHA): SA, sp.cos(ALPHA): CA, sp.sin(BETA): SB, sp.cos(BETA): CB})
    expr = sp.factor(sp.cancel(sp.together(expr)))
    return expr.subs(SA**2 + CA**2 * CB**2, D_SCALED)


def christoffel_coriolis(mass: sp.Matrix) -> sp.Matrix:
    """Christoffel-form C(q, qdot) of a 2x2 inertia matrix in (alpha, beta)."""
    grad = [mass.diff(coordinate) for coordinate in COORDINATES]
    coriolis = sp.zeros(2, 2)
    for k in range(2):
        for j in range(2):
            coriolis[k, j] = sum(
                sp.Rational(1, 2) * (grad[i][k, j] + grad[j][k, i] - grad[k][i, j]) * VELOCITIES[i]
                for i in range(2)
            )
    return coriolis


def _function_source(
    name: str,
    doc: str,
    arguments: Sequence[sp.Symbol],
    outputs: Sequence[tuple[str, sp.Expr]],
) -> str:
    replacements, reduced = sp.cse([expr for _, expr in outputs], symbols=sp.numbered_symbols("t"))
    used = set().union(*(expr.free_symbols for expr in reduced), *(e.free_symbols for _, e in replacements))
    args = [arg for arg in arguments if arg in used or arg is D_SCALED]
    signature = ", ".join(f"{arg}: Real" for arg in args if arg is not D_SCALED)
    lines = [
        f"def {name}({signature}) -> tuple[Real, ...]:",
        f'    """{doc}"""',
    ]
    if D_SCALED in used:
        lines.append(f"    {D_SCALED} = sa**2 + ca**2 * cb**2")
    for symbol, expr in replacements:
        lines.append(f"    {symbol} = {sp.pycode(expr)}")
    for (label, _), expr in zip(outputs, reduced, strict=True):
        lines.append(f"    {label} = {sp.pycode(expr)}")
    lines.append(f"    return ({', '.join(label for label, _ in outputs)},)")
    return "\n".join(lines) + "\n"


def generate_source() -> str:
    """Returns the text of ``_generated.py``."""
    mass = printed_mass_matrix()
    theta = spin_angle()
    grad_mass = [mass.diff(coordinate) for coordinate in COORDINATES]
    coriolis = christoffel_coriolis(mass)
    trig_args = (SA, CA, SB, CB)
    inertia_args = (I11, I22, I44, I55)

    functions = [
        _function_source(
            "spin_angle_gradient_entries",
            "(dtheta/dalpha, dtheta/dbeta) of theta = atan2(tan(alpha), cos(beta)) (dimensionless).",
            trig_args,
            [(f"dtheta_d{q}", to_sin_cos(sp.diff(theta, q))) for q in COORDINATES],
        ),
        _function_source(
            "mass_matrix_entries",
            "(M11, M12, M22) of Appendix A (kg m^2); M21 = M12.",
            (*trig_args, *inertia_args),
            [(f"m{i + 1}{j + 1}", to_sin_cos(mass[i, j])) for i, j in ((0, 0), (0, 1), (1, 1))],
        ),
        _function_source(
            "mass_matrix_gradient_entries",
            "(dM11, dM12, dM22)/dalpha then (dM11, dM12, dM22)/dbeta (kg m^2/rad).",
            (*trig_args, *inertia_args),
            [
                (f"dm{ij}_d{q}", to_sin_cos(grad[index]))
                for q, grad in zip(COORDINATES, grad_mass, strict=True)
                for ij, index in (("11", (0, 0)), ("12", (0, 1)), ("22", (1, 1)))
            ],
        ),
        _function_source(
            "coriolis_matrix_entries",
            "(C11, C12, C21, C22) of the Christoffel form (N m s/rad).",
            (*trig_args, ALPHA_DOT, BETA_DOT, *inertia_args),
            [(f"c{k + 1}{j + 1}", to_sin_cos(coriolis[k, j])) for k in range(2) for j in range(2)],
        ),
    ]
    header = (
        '"""Closed-form dynamics terms of the SMM.\n\n'
        "generated by tools/generate_dynamics.py, do not edit.\n"
        f"sympy {sp.__version__}. Arguments sa, ca, sb, cb are sin/cos of alpha and beta;\n"
        "d_scaled = cos^2(alpha) (tan^2(alpha) + cos^2(beta)). Arithmetic only: arguments may be floats\n"
        'or broadcastable numpy arrays.\n"""\n\n'
        "# ruff: noqa\n"
        "from typing import Any\n\n"
        "Real = Any  # float or numpy array\n"
    )
    return header + "".join(f"\n\n{function}" for function in functions)


def main(argv: Sequence[str] | None = None) -> None:
    """Writes the generated module."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="file to write")
    args = parser.parse_args(argv)
    args.output.write_text(generate_source(), encoding="utf-8")


if __name__ == "__main__":
    main()
