"""Typed errors of the analysis library (each a ``ValueError``, so one ``except`` catches them all)."""

__all__ = [
    "AnalysisError",
    "ClosedLoopDivergedError",
    "MetricsInputError",
    "ParamsFileError",
    "UnknownControllerError",
    "UnknownScenarioError",
]


class AnalysisError(ValueError):
    """Base class of every error raised by ``smm_analysis``."""


class MetricsInputError(AnalysisError):
    """Arrays given to a metric are malformed: wrong shape or length, NaN/Inf, time not increasing."""


class UnknownScenarioError(AnalysisError):
    """A scenario name is not in ``smm_analysis.scenarios.SCENARIOS``."""


class UnknownControllerError(AnalysisError):
    """A controller name is not one of the controllers the closed loop can run."""


class ClosedLoopDivergedError(AnalysisError):
    """The control chain produced a non-finite torque: the closed loop went unstable."""


class ParamsFileError(AnalysisError):
    """A parameters file for ``smm-bag rerun`` is unreadable or holds invalid gains."""
