"""Rigid-body model of the 2-DOF hydraulic spherical motion mechanism (pure numpy)."""
