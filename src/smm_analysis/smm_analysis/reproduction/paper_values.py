"""Numbers the paper reports (SPEC section 6), for the side-by-side tables of the report.

Only what the paper states is here; a missing entry means the paper gives no number. Units: rad, s,
and the paper's control energy (eq. 45, N^2 m^2 s), per joint (alpha, beta).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

__all__ = [
    "PAPER_CASE1",
    "PAPER_CASE1_FPDESO_RMS_REDUCTION",
    "PAPER_CASE2",
    "PAPER_END_EFFECTOR_MAX_MM",
    "PAPER_STEP",
    "PaperJointValues",
]

PaperJointValues = Mapping[str, tuple[float, float]]
"""Metric name -> (alpha, beta)."""

PAPER_STEP: Mapping[str, PaperJointValues] = MappingProxyType(
    {
        "pid": MappingProxyType({"rise_time": (0.01, 0.01), "overshoot": (0.153, 0.195)}),
        "npd": MappingProxyType({"rise_time": (0.08, 0.07), "overshoot": (0.075, 0.022)}),
        "fpd": MappingProxyType({"rise_time": (0.14, 0.09), "overshoot": (0.0, 0.0)}),
        "fpdeso": MappingProxyType({"rise_time": (0.06, 0.05), "overshoot": (0.0, 0.0)}),
    }
)
"""Section V.A, Figs 12-13: rise time (s; the paper does not define it) and overshoot (rad;
FPDESO 'almost no overshoot')."""

PAPER_CASE1: Mapping[str, PaperJointValues] = MappingProxyType(
    {
        "pid": MappingProxyType({"Ma": (0.012, 0.003)}),
        "npd": MappingProxyType({"Ma": (0.007, 0.003)}),
        "fpdeso": MappingProxyType({"RMS": (0.0022, 0.0012), "eps_u": (24.44, 2.126)}),
    }
)
"""Case 1 (Figs 14-17, text on Table 3, whose body is not in the text): FPDESO's RMS is 29 % / 29.4 %
lower than FPD's."""

PAPER_CASE1_FPDESO_RMS_REDUCTION: tuple[float, float] = (0.29, 0.294)
"""Case 1: FPDESO RMS below FPD's by this fraction (alpha, beta)."""

PAPER_CASE2: Mapping[str, PaperJointValues] = MappingProxyType(
    {
        "fpd": MappingProxyType(
            {"Ma": (0.127, 0.131), "Ave": (0.0564, 0.0513), "RMS": (0.0274, 0.0168), "eps_u": (43.44, 24.67)}
        ),
        "fpdeso": MappingProxyType(
            {"Ma": (0.099, 0.095), "Ave": (0.044, 0.040), "RMS": (0.0120, 0.0105), "eps_u": (38.63, 11.01)}
        ),
    }
)
"""Case 2, Table 4."""

PAPER_END_EFFECTOR_MAX_MM: Mapping[str, Mapping[str, float]] = MappingProxyType(
    {
        "fpd": MappingProxyType({"x": 1.518, "y": 2.022, "z": 1.913}),
        "fpdeso": MappingProxyType({"x": 0.924, "y": 1.078, "z": 1.071}),
    }
)
"""Bench experiment (Section V.B, Table 6): maximal absolute end-effector error (mm). A bench result,
not a simulation; shown for orientation only."""
