#!/usr/bin/env python3
"""Generates ``smm_dynamics/_generated.py`` from the inertia matrix printed in the paper's Appendix A.

Derives the Coriolis matrix by Christoffel symbols and the cheaper spin-angle forms with sympy, proves them
against the printed M, and emits arithmetic-only functions of sin/cos (docs/DYNAMICS.md, "Coriolis matrix").

Usage: ``python tools/generate_dynamics.py [--output PATH]`` (default: the package's ``_generated.py``).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import sympy as sp
from sympy.printing.precedence import precedence
from sympy.printing.pycode import PythonCodePrinter

ALPHA, BETA = sp.symbols("alpha beta", real=True)
ALPHA_DOT, BETA_DOT = sp.symbols("alpha_dot beta_dot", real=True)
I11, I22, I44, I55 = sp.symbols("I11 I22 I44 I55", positive=True)
SA, CA, SB, CB = sp.symbols("sa ca sb cb", real=True)
# D = tan^2(alpha) + cos^2(beta) of Appendix A, times cos^2(alpha):
D_SCALED = sp.Symbol("d_scaled", positive=True)

COORDINATES = (ALPHA, BETA)
VELOCITIES = (ALPHA_DOT, BETA_DOT)

# Intermediate quantities of the spin form (see the module docstring).
INV_D, G_ALPHA, G_BETA = sp.symbols("inv_d g_alpha g_beta", real=True)
HALF_I11, ROTOR_ALPHA = sp.symbols("half_I11 rotor_alpha", real=True)
THETA_DOT, SPIN_CURVATURE = sp.symbols("theta_dot spin_curvature", real=True)
M11, M12, M22 = sp.symbols("m11 m12 m22", real=True)
CORIOLIS_ALPHA, CORIOLIS_BETA = sp.symbols("coriolis_alpha coriolis_beta", real=True)
TORQUE_ALPHA, TORQUE_BETA = sp.symbols("torque_alpha torque_beta", real=True)
RHS_ALPHA, RHS_BETA, INV_DET = sp.symbols("rhs_alpha rhs_beta inv_det", real=True)
QDD_ALPHA, QDD_BETA = sp.symbols("qdd_alpha qdd_beta", real=True)
# Pythagoras on factors that sympy's factor() leaves behind.
_PYTHAGORAS = {
    (CB - 1) * (CB + 1): -(SB**2),
    CA**2 + SA**2: 1,
    CB**2 + SB**2: 1,
    SA**2 + CA**2 * CB**2: D_SCALED,
}

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


class _FloatPrinter(PythonCodePrinter):  # type: ignore[misc]
    """Python printer that writes x**2 .. x**4 as products, which Python evaluates faster on floats."""

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        base, exponent = expr.as_base_exp()
        if exponent.is_Integer and 2 <= int(exponent) <= 4:
            factor = self._print(base) if base.is_Symbol else f"({self._print(base)})"
            # Parenthesised so that a product printed as a denominator stays one.
            return "(" + "*".join([factor] * int(exponent)) + ")"
        return str(super()._print_Pow(expr, rational))

    def _print_Add(self, expr: sp.Add, order: str | None = None) -> str:
        # Terms with a positive sign first, so that a - b is printed rather than -b + a (one negation
        # less per sum in the generated code).
        terms = expr.as_ordered_terms()
        positive = [term for term in terms if not term.could_extract_minus_sign()]
        negative = [term for term in terms if term.could_extract_minus_sign()]
        if not positive:
            return str(super()._print_Add(expr, order))
        text = " + ".join(self.parenthesize(term, precedence(expr)) for term in positive)
        for term in negative:
            text += " - " + self.parenthesize(-term, precedence(expr))
        return text

    def _print_sin(self, expr: sp.sin) -> str:
        return f"sin({self._print(expr.args[0])})"

    def _print_cos(self, expr: sp.cos) -> str:
        return f"cos({self._print(expr.args[0])})"


def _vanishes(expr: sp.Expr) -> bool:
    """Whether a rational function of sa, ca, sb, cb (and d_scaled) is identically 0 on sin^2 + cos^2 = 1."""
    numerator = sp.numer(sp.cancel(sp.together(expr.subs(D_SCALED, SA**2 + CA**2 * CB**2))))
    remainder = sp.reduced(sp.expand(numerator), [SA**2 + CA**2 - 1, SB**2 + CB**2 - 1], SA, SB, CA, CB)[1]
    return bool(remainder == 0)


def _substitute_stages(expr: sp.Expr, stages: Sequence[tuple[sp.Symbol, sp.Expr]]) -> sp.Expr:
    """Expands the intermediate symbols of ``stages`` (later stages may use earlier ones)."""
    for symbol, value in reversed(stages):
        expr = expr.subs(symbol, value)
    return expr


Stages = list[tuple[sp.Symbol, sp.Expr]]


def spin_form_stages() -> tuple[Stages, Stages, Stages]:
    """Assignments of the spin form: (constants, M stages, C q' stages), each in evaluation order.

    The gradient of theta and the spin curvature s = q'^T H q' are derived here from
    theta = atan2(tan(alpha), cos(beta)); M and C q' in terms of them follow from the kinetic energy
    of the module docstring, and :func:`check_spin_form` proves them equal to the printed M and the
    Christoffel C q'.
    """
    theta = spin_angle()
    gradient = [to_sin_cos(sp.diff(theta, q)).subs(_PYTHAGORAS) for q in COORDINATES]
    curvature = sum(
        sp.diff(theta, q_i, q_j) * rate_i * rate_j
        for q_i, rate_i in zip(COORDINATES, VELOCITIES, strict=True)
        for q_j, rate_j in zip(COORDINATES, VELOCITIES, strict=True)
    )
    scaled = sp.Poly(sp.expand(sp.cancel(to_sin_cos(curvature) * D_SCALED**2)), *VELOCITIES)
    curvature_numerator = sum(
        sp.factor(coefficient).subs(_PYTHAGORAS) * ALPHA_DOT**i * BETA_DOT**j
        for (i, j), coefficient in scaled.terms()
    )
    constant_stages = [(HALF_I11, sp.Rational(1, 2) * I11)]
    mass_stages = [
        (D_SCALED, SA**2 + CA**2 * CB**2),
        (INV_D, 1 / D_SCALED),
        (G_ALPHA, gradient[0].subs(D_SCALED, 1 / INV_D)),
        (G_BETA, gradient[1].subs(D_SCALED, 1 / INV_D)),
        (ROTOR_ALPHA, I55 * G_ALPHA),
        (M11, I44 + (ROTOR_ALPHA - I11 * CB) * G_ALPHA),
        (M12, (ROTOR_ALPHA - HALF_I11 * CB) * G_BETA),
        (M22, I22 + I55 * G_BETA**2),
    ]
    coriolis_stages = [
        (THETA_DOT, G_ALPHA * ALPHA_DOT + G_BETA * BETA_DOT),
        (SPIN_CURVATURE, curvature_numerator * INV_D**2),
        (
            CORIOLIS_ALPHA,
            ROTOR_ALPHA * SPIN_CURVATURE
            + HALF_I11
            * (SB * BETA_DOT * THETA_DOT + SB * ALPHA_DOT * BETA_DOT * G_ALPHA - CB * SPIN_CURVATURE),
        ),
        (
            CORIOLIS_BETA,
            I55 * SPIN_CURVATURE * G_BETA + HALF_I11 * SB * ALPHA_DOT * (BETA_DOT * G_BETA - THETA_DOT),
        ),
    ]
    return constant_stages, mass_stages, coriolis_stages


def check_spin_form(stages: Sequence[tuple[sp.Symbol, sp.Expr]]) -> None:
    """Raises AssertionError unless the spin form equals the printed M and the Christoffel C q'."""
    mass = printed_mass_matrix()
    coriolis_vector = christoffel_coriolis(mass) * sp.Matrix(VELOCITIES)
    expected = {
        M11: mass[0, 0],
        M12: mass[0, 1],
        M22: mass[1, 1],
        CORIOLIS_ALPHA: coriolis_vector[0],
        CORIOLIS_BETA: coriolis_vector[1],
    }
    for symbol, reference in expected.items():
        difference = _substitute_stages(symbol, stages) - to_sin_cos(reference)
        if not _vanishes(difference):
            raise AssertionError(f"spin form of {symbol} differs from the reference")


def _staged_lines(
    stages: Sequence[tuple[sp.Symbol, sp.Expr]], defined: set[sp.Symbol], temporary_prefix: str = "t"
) -> list[str]:
    """Assignment lines of ``stages`` with common subexpressions extracted; ``defined`` grows."""
    printer = _FloatPrinter()
    lines: list[str] = []
    # ROTOR_ALPHA is left alone: cse would otherwise pull out -rotor_alpha, one negation more.
    replacements, reduced = sp.cse(
        [expr for _, expr in stages],
        symbols=sp.numbered_symbols(temporary_prefix),
        ignore=tuple(symbol for symbol, _ in stages if symbol.name.startswith("rotor_alpha")),
    )
    pending = list(replacements)

    def emit_ready_replacements() -> None:
        # A common subexpression is written as soon as everything it uses is defined.
        ready = True
        while ready:
            ready = False
            for replacement in pending:
                symbol, expr = replacement
                if expr.free_symbols <= defined:
                    lines.append(f"    {symbol} = {printer.doprint(expr)}")
                    defined.add(symbol)
                    pending.remove(replacement)
                    ready = True
                    break

    for (symbol, _), expr in zip(stages, reduced, strict=True):
        emit_ready_replacements()
        lines.append(f"    {symbol} = {printer.doprint(expr)}")
        defined.add(symbol)
    return lines


def _staged_function_source(
    name: str,
    doc: str,
    arguments: Sequence[sp.Symbol],
    stages: Sequence[tuple[sp.Symbol, sp.Expr]],
    outputs: Sequence[sp.Symbol],
) -> str:
    signature = ", ".join(f"{arg}: Real" for arg in arguments)
    lines = [f"def {name}({signature}) -> tuple[Real, ...]:", f'    """{doc}"""']
    lines.extend(_staged_lines(stages, set(arguments)))
    lines.append(f"    return ({', '.join(str(symbol) for symbol in outputs)},)")
    return "\n".join(lines) + "\n"


# Arguments of the fused RK4 step besides the state and the inertias (see _rk4_function_source).
LOAD_ALPHA, LOAD_BETA = sp.symbols("load_alpha load_beta", real=True)
FRICTION_ALPHA, FRICTION_BETA, GRAVITY = sp.symbols("friction_alpha friction_beta gravity", real=True)
DT = sp.Symbol("dt", positive=True)

# The same stages, in the same order and with the same arithmetic, as smm_dynamics.integration.rk4_stages.
_RK4_COMBINATION = """\
    half = 0.5 * dt
{stage_1}
    alpha_dot_2 = alpha_dot + half * qdd_alpha_1
    beta_dot_2 = beta_dot + half * qdd_beta_1
    alpha_2 = alpha + half * alpha_dot
    beta_2 = beta + half * beta_dot
{stage_2}
    alpha_dot_3 = alpha_dot + half * qdd_alpha_2
    beta_dot_3 = beta_dot + half * qdd_beta_2
    alpha_3 = alpha + half * alpha_dot_2
    beta_3 = beta + half * beta_dot_2
{stage_3}
    alpha_dot_4 = alpha_dot + dt * qdd_alpha_3
    beta_dot_4 = beta_dot + dt * qdd_beta_3
    alpha_4 = alpha + dt * alpha_dot_3
    beta_4 = beta + dt * beta_dot_3
{stage_4}
    sixth = dt / 6.0
    alpha_next = alpha + sixth * (alpha_dot + 2.0 * alpha_dot_2 + 2.0 * alpha_dot_3 + alpha_dot_4)
    beta_next = beta + sixth * (beta_dot + 2.0 * beta_dot_2 + 2.0 * beta_dot_3 + beta_dot_4)
    alpha_dot_next = alpha_dot + sixth * (qdd_alpha_1 + 2.0 * qdd_alpha_2 + 2.0 * qdd_alpha_3 + qdd_alpha_4)
    beta_dot_next = beta_dot + sixth * (qdd_beta_1 + 2.0 * qdd_beta_2 + 2.0 * qdd_beta_3 + qdd_beta_4)
    return (alpha_next, beta_next, alpha_dot_next, beta_dot_next,)
"""


def _rk4_function_source(
    constant_stages: Sequence[tuple[sp.Symbol, sp.Expr]], dynamics_stages: Sequence[tuple[sp.Symbol, sp.Expr]]
) -> str:
    """One classical RK4 step with the four evaluations of q'' written out (no call per stage).

    The torque of each evaluation is load - F q' - G(q) with the viscous friction F and the
    gravity coefficient of G_beta = gravity sin(beta) passed in.
    """
    arguments = (
        *COORDINATES,
        *VELOCITIES,
        LOAD_ALPHA,
        LOAD_BETA,
        FRICTION_ALPHA,
        FRICTION_BETA,
        GRAVITY,
        DT,
        I11,
        I22,
        I44,
        I55,
    )
    defined = set(arguments)
    constant_lines = "\n".join(_staged_lines(constant_stages, defined))
    stage_lines = {}
    for k in range(1, 5):
        state = (
            (*COORDINATES, *VELOCITIES)
            if k == 1
            else sp.symbols(f"alpha_{k} beta_{k} alpha_dot_{k} beta_dot_{k}", real=True)
        )
        defined.update(state)
        renamed = {
            symbol: sp.Symbol(f"{symbol}_{k}", real=True)
            for symbol in (
                SA,
                CA,
                SB,
                CB,
                TORQUE_ALPHA,
                TORQUE_BETA,
                *(symbol for symbol, _ in dynamics_stages),
            )
        }
        renamed.update(dict(zip((ALPHA_DOT, BETA_DOT), state[2:], strict=True)))
        stages = [
            (renamed[SA], sp.sin(state[0])),
            (renamed[CA], sp.cos(state[0])),
            (renamed[SB], sp.sin(state[1])),
            (renamed[CB], sp.cos(state[1])),
            (renamed[TORQUE_ALPHA], LOAD_ALPHA - FRICTION_ALPHA * state[2]),
            (renamed[TORQUE_BETA], LOAD_BETA - GRAVITY * renamed[SB] - FRICTION_BETA * state[3]),
            *((symbol.xreplace(renamed), expr.xreplace(renamed)) for symbol, expr in dynamics_stages),
        ]
        stage_lines[f"stage_{k}"] = "\n".join(_staged_lines(stages, defined, f"t{k}_"))
    signature = ", ".join(f"{arg}: float" for arg in arguments)
    return (
        f"def rk4_step_spin_form({signature}) -> tuple[float, ...]:\n"
        '    """One RK4 step of the spin form on floats: (alpha, beta, alpha\', beta\') after dt.\n\n'
        "    Angles in rad, rates in rad/s. q'' = M^-1 (load - F q' - G(q) - C q') with\n"
        "    F = diag(friction_alpha, friction_beta) (N m s/rad), G = (0, gravity sin(beta)) (N m) and\n"
        "    load = tau - tau_dist (N m) held over the step. Floats only (math.sin, math.cos).\n"
        '    """\n'
        "    sin = math.sin\n"
        "    cos = math.cos\n" + constant_lines + "\n" + _RK4_COMBINATION.format(**stage_lines)
    )


def spin_form_functions() -> list[str]:
    """Sources of the spin-form functions (M; M and C q'; q''; one RK4 step)."""
    constant_stages, mass_stages, coriolis_stages = spin_form_stages()
    check_spin_form([*constant_stages, *mass_stages, *coriolis_stages])
    solve_stages = [
        (RHS_ALPHA, TORQUE_ALPHA - CORIOLIS_ALPHA),
        (RHS_BETA, TORQUE_BETA - CORIOLIS_BETA),
        (INV_DET, 1 / (M11 * M22 - M12**2)),
        (QDD_ALPHA, (M22 * RHS_ALPHA - M12 * RHS_BETA) * INV_DET),
        (QDD_BETA, (M11 * RHS_BETA - M12 * RHS_ALPHA) * INV_DET),
    ]
    trig_args = (SA, CA, SB, CB)
    inertia_args = (I11, I22, I44, I55)
    return [
        _staged_function_source(
            "mass_matrix_entries_spin_form",
            "(M11, M12, M22) (kg m^2), equal to mass_matrix_entries up to rounding.",
            (*trig_args, *inertia_args),
            [*constant_stages, *mass_stages],
            (M11, M12, M22),
        ),
        _staged_function_source(
            "rigid_body_entries_spin_form",
            "(M11, M12, M22) (kg m^2) and C q' (N m), equal to the reference entries up to rounding.",
            (*trig_args, ALPHA_DOT, BETA_DOT, *inertia_args),
            [*constant_stages, *mass_stages, *coriolis_stages],
            (M11, M12, M22, CORIOLIS_ALPHA, CORIOLIS_BETA),
        ),
        _staged_function_source(
            "forward_dynamics_entries_spin_form",
            "q'' = M^-1 (torque - C q') (rad/s^2); torque = tau - G - F - tau_dist (N m).",
            (*trig_args, ALPHA_DOT, BETA_DOT, TORQUE_ALPHA, TORQUE_BETA, *inertia_args),
            [*constant_stages, *mass_stages, *coriolis_stages, *solve_stages],
            (QDD_ALPHA, QDD_BETA),
        ),
        _rk4_function_source(constant_stages, [*mass_stages, *coriolis_stages, *solve_stages]),
    ]


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
        *spin_form_functions(),
    ]
    header = (
        '"""Closed-form dynamics terms of the SMM.\n\n'
        "generated by tools/generate_dynamics.py, do not edit.\n"
        f"sympy {sp.__version__}. Arguments sa, ca, sb, cb are sin/cos of alpha and beta;\n"
        "d_scaled = cos^2(alpha) (tan^2(alpha) + cos^2(beta)). Arithmetic only: arguments may be floats\n"
        'or broadcastable numpy arrays.\n"""\n\n'
        "# ruff: noqa\n"
        "import math\n"
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
