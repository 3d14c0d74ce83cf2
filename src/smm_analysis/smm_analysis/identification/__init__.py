"""Identification of the SMM's parameters from recorded runs (docs/IDENTIFICATION.md)."""

from smm_analysis.identification.data import PreparedRun, prepare_run
from smm_analysis.identification.estimate import EstimationSettings, Identification, RunFit, fit_of, identify
from smm_analysis.identification.filtering import FilterSettings, Segment
from smm_analysis.identification.regressor import (
    PARAMETER_NAMES,
    PARAMETER_UNITS,
    parameter_vector,
    parameters_from_vector,
    regressor,
)

__all__ = [
    "PARAMETER_NAMES",
    "PARAMETER_UNITS",
    "EstimationSettings",
    "FilterSettings",
    "Identification",
    "PreparedRun",
    "RunFit",
    "Segment",
    "fit_of",
    "identify",
    "parameter_vector",
    "parameters_from_vector",
    "prepare_run",
    "regressor",
]
