"""The generated closed forms in spin form (sin/cos evaluated once), for the batched loops of other packages.

The public names of ``smm_dynamics._generated`` (tools/generate_dynamics.py makes it) that
``smm_analysis.batch`` evaluates on arrays; the scalar model uses the same functions.
"""

from smm_dynamics._generated import (
    forward_dynamics_entries_spin_form,
    mass_matrix_entries_spin_form,
    rigid_body_entries_spin_form,
)

__all__ = [
    "forward_dynamics_entries_spin_form",
    "mass_matrix_entries_spin_form",
    "rigid_body_entries_spin_form",
]
