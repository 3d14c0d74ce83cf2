"""Typed errors of the analysis library (each a ``ValueError``, so one ``except`` catches them all)."""

__all__ = [
    "AnalysisError",
    "ClosedLoopDivergedError",
    "IdentificationError",
    "IdentificationInputError",
    "MetricsInputError",
    "MissingSignalsError",
    "NotEnoughDataError",
    "NotExcitingError",
    "NotPhysicalError",
    "ParamsFileError",
    "SaturatedRunError",
    "StopsRunError",
    "UnknownControllerError",
    "UnknownParameterError",
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


class UnknownParameterError(ParamsFileError):
    """A parameters file sets a name, or has a node section, that no node of the stack declares."""


class IdentificationError(AnalysisError):
    """Base class of the errors of ``smm_analysis.identification``: the data cannot give a sound model."""


class IdentificationInputError(IdentificationError):
    """Arrays given to the identification are malformed: shapes, NaN/Inf, stamps not increasing."""


class MissingSignalsError(IdentificationError):
    """A run lacks a signal the identification needs (positions, or the applied torque: the effort)."""


class NotEnoughDataError(IdentificationError):
    """Too little usable motion (too short, or too much left out) for an estimate."""


class SaturatedRunError(IdentificationError):
    """The applied torque sat at its limit for too long: the model's torque is not what acted."""


class StopsRunError(IdentificationError):
    """A joint sat at a mechanical stop for too long: the stop's torque is not in the model."""


class NotExcitingError(IdentificationError):
    """The data do not separate every parameter (rank deficient regressor); the message names them."""


class NotPhysicalError(IdentificationError):
    """The estimate is not a physical model (M(q) not positive definite over the workspace)."""
