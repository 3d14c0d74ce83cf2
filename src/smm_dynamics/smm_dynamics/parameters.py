"""Physical parameters of the spherical motion mechanism (SPEC section 1, paper Table 2).

The inertias I11, I22, I44, I55 (kg m^2) and the gravity lever m_c l_c (kg m) are computed from Table 2's
body data; the mapping: docs/DYNAMICS.md, "Inertia mapping".
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from smm_schema.ranges import above, at_least, bounds, check_bounds, no_range

__all__ = ["TABLE2_BODIES", "BodyData", "SMMParameters"]


@dataclass(frozen=True)
class BodyData:
    """One rigid part of the SMM as listed in Table 2 of the paper.

    Attributes:
        name: Part name.
        mass: Mass (kg).
        length: Offset of the centre of mass from the sphere centre along the spin axis (m).
        inertia: Principal inertias (Ixx, Iyy, Izz) about the part's centre of mass (kg m^2);
            z is the spin axis.
    """

    name: str
    mass: float
    length: float
    inertia: tuple[float, float, float]


#: Table 2 of the paper (lengths converted from mm to m).
TABLE2_BODIES: tuple[BodyData, ...] = (
    BodyData("rudder_blade", 3.9, 5.0e-3, (0.027, 0.027, 0.005)),
    BodyData("spin_motor", 1.2, 3.5e-3, (0.01, 0.01, 0.01)),
    BodyData("rotor", 5.4, 3.0e-3, (0.032, 0.032, 0.056)),
)


def _transverse_inertia(bodies: tuple[BodyData, ...]) -> float:
    return sum(body.inertia[0] + body.mass * body.length**2 for body in bodies)


def _axial_inertia(bodies: tuple[BodyData, ...]) -> float:
    return sum(body.inertia[2] for body in bodies)


def _mass_lever(bodies: tuple[BodyData, ...]) -> float:
    return sum(body.mass * body.length for body in bodies)


_DEFAULT_TRANSVERSE_INERTIA = _transverse_inertia(TABLE2_BODIES)
_DEFAULT_AXIAL_INERTIA = _axial_inertia(TABLE2_BODIES)
_DEFAULT_MASS_LEVER = _mass_lever(TABLE2_BODIES)


def _require_finite(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")


@dataclass(frozen=True)
class SMMParameters:
    """Rigid-body parameters of the 2-DOF SMM plant model.

    Attributes:
        I11: Transverse inertia term of Appendix A (kg m^2), > 0.
        I22: Inertia about the tilt (beta) axis (kg m^2), > 0.
        I44: Inertia about the alpha axis (kg m^2), > 0.
        I55: Axial (spin) inertia of the rotor (kg m^2), > 0.
        mass_lever: Gravity lever m_c l_c (kg m), >= 0.
        gravity: Gravitational acceleration (m/s^2), >= 0.
        gravity_sign: +1.0: end effector up at rest, V = +m_c g l_c cos(beta) (open-loop unstable);
            -1.0: the end effector hangs down (V = -m_c g l_c cos(beta)).
        viscous_friction: Viscous friction coefficients (alpha, beta) (N m s/rad), >= 0.
        link_length: Distance L from the sphere centre to the end effector (m), > 0.
        coulomb_friction: Coulomb friction levels (alpha, beta) (N m), >= 0; F gains f_c sign(q').
        torque_offset: Constant torque offsets (alpha, beta) (N m), finite; F gains them as they are.

    The friction torque is F(q') = f_v q' + f_c sign(q') + offset per joint, sign(0) = 0.
    """

    I11: float = field(default=_DEFAULT_TRANSVERSE_INERTIA, metadata=above(0.0))
    I22: float = field(default=_DEFAULT_TRANSVERSE_INERTIA, metadata=above(0.0))
    I44: float = field(default=_DEFAULT_TRANSVERSE_INERTIA, metadata=above(0.0))
    I55: float = field(default=_DEFAULT_AXIAL_INERTIA, metadata=above(0.0))
    mass_lever: float = field(default=_DEFAULT_MASS_LEVER, metadata=at_least(0.0))
    gravity: float = field(default=9.81, metadata=at_least(0.0))
    gravity_sign: float = field(default=1.0, metadata=bounds(-1.0, 1.0))
    viscous_friction: tuple[float, float] = field(default=(0.1, 0.1), metadata=at_least(0.0))
    link_length: float = field(default=0.1, metadata=above(0.0))
    coulomb_friction: tuple[float, float] = field(default=(0.0, 0.0), metadata=at_least(0.0))
    torque_offset: tuple[float, float] = field(default=(0.0, 0.0), metadata=no_range())

    def __post_init__(self) -> None:
        check_bounds(self)
        if self.gravity_sign not in (-1.0, 1.0) or isinstance(self.gravity_sign, bool):
            raise ValueError(f"gravity_sign must be +1.0 or -1.0, got {self.gravity_sign!r}")

    @classmethod
    def from_table2(cls, bodies: tuple[BodyData, ...] = TABLE2_BODIES, **overrides: float) -> SMMParameters:
        """Builds the parameters from body data with the mapping of the module docstring.

        Args:
            bodies: Rigid parts (default: Table 2 of the paper).
            **overrides: Any other field of SMMParameters (gravity, link_length, ...).

        Returns:
            Parameters with I11 = I22 = I44 = sum(Ixx_i + m_i l_i^2), I55 = sum(Izz_i) and
            mass_lever = sum(m_i l_i).
        """
        transverse = _transverse_inertia(bodies)
        fields: dict[str, object] = {
            "I11": transverse,
            "I22": transverse,
            "I44": transverse,
            "I55": _axial_inertia(bodies),
            "mass_lever": _mass_lever(bodies),
        }
        fields.update(overrides)
        return cls(**fields)  # type: ignore[arg-type]

    def with_inertia_scale(self, factor: float) -> SMMParameters:
        """Returns a copy with the four inertias I11, I22, I44, I55 multiplied by ``factor``.

        This is SPEC case2's "plant inertias +10 %" (factor 1.1). The gravity lever m_c l_c,
        friction and geometry are left unchanged: the model error is in the inertia only.

        Args:
            factor: Positive finite scale (dimensionless).

        Returns:
            The scaled parameters.
        """
        _require_finite("factor", factor)
        if factor <= 0.0:
            raise ValueError(f"factor must be > 0, got {factor!r}")
        return dataclasses.replace(
            self,
            I11=self.I11 * factor,
            I22=self.I22 * factor,
            I44=self.I44 * factor,
            I55=self.I55 * factor,
        )
