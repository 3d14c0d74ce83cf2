"""Rigid-body model of the 2-DOF hydraulic spherical motion mechanism (pure numpy)."""

from smm_dynamics.fast_path import (
    forward_dynamics_floats,
    friction_floats,
    mass_matrix_floats,
    rigid_body_floats,
    rk4_step_floats,
)
from smm_dynamics.integration import rk4_stages, rk4_step
from smm_dynamics.kinematics import end_effector_position, spin_angle, spin_angle_gradient
from smm_dynamics.model import (
    coriolis_matrix,
    coriolis_vector,
    forward_dynamics,
    friction_torque,
    gravity_vector,
    inverse_dynamics,
    kinetic_energy,
    mass_matrix,
    mass_matrix_gradient,
    mass_matrix_inverse,
    mass_matrix_time_derivative,
    potential_energy,
    rigid_body_terms,
    total_energy,
)
from smm_dynamics.parameters import TABLE2_BODIES, BodyData, SMMParameters

__all__ = [
    "TABLE2_BODIES",
    "BodyData",
    "SMMParameters",
    "coriolis_matrix",
    "coriolis_vector",
    "end_effector_position",
    "forward_dynamics",
    "forward_dynamics_floats",
    "friction_floats",
    "friction_torque",
    "gravity_vector",
    "inverse_dynamics",
    "kinetic_energy",
    "mass_matrix",
    "mass_matrix_floats",
    "mass_matrix_gradient",
    "mass_matrix_inverse",
    "mass_matrix_time_derivative",
    "potential_energy",
    "rigid_body_floats",
    "rigid_body_terms",
    "rk4_stages",
    "rk4_step",
    "rk4_step_floats",
    "spin_angle",
    "spin_angle_gradient",
    "total_energy",
]
