"""FPDESO controller of the SMM: TD, fuzzy PD, FLESO, robust term, baselines, and their nodes.

The algorithm modules (everything but ``*_node.py``) are pure numpy, take time as ``dt`` and import no
ROS package.
"""

from smm_controller.baselines import (
    FPDConfig,
    FPDController,
    NPDConfig,
    NPDController,
    PIDConfig,
    PIDController,
    npd_gain,
)
from smm_controller.chain import (
    ControlChain,
    JointController,
    build_chain,
    make_chain,
    make_controller,
)
from smm_controller.fleso import DEFAULT_FLESO_W_MIN, FLESO, FLESOConfig, observer_gains
from smm_controller.fpdeso import FPDESOConfig, FPDESOController, robust_switch
from smm_controller.fuzzy import (
    ZERO_AREA_FALLBACK,
    FuzzyVariable,
    GaussianMF,
    MamdaniSystem,
    TriangularMF,
    centroid,
    centroid_weights,
    gaussian_mf,
    triangular_mf,
)
from smm_controller.fuzzy_batch import MamdaniBatch
from smm_controller.fuzzy_pd import (
    PAPER_FPD_FUZZY,
    PAPER_FPDESO_FUZZY,
    FuzzyPDConfig,
    FuzzyPDGainSchedule,
)
from smm_controller.laws import Law, UnknownLawError, get_law, law_names, law_table
from smm_controller.model import NominalModel
from smm_controller.reference import (
    REFERENCE_KINDS,
    RampHoldReference,
    Reference,
    SineReference,
    StepReference,
    make_reference,
)
from smm_controller.rules import TABLE_1, TABLE_7, RuleTable
from smm_controller.td import (
    DEFAULT_TD_FILTER_FACTOR,
    DEFAULT_TD_SPEED,
    TrackingDifferentiator,
    TrackingDifferentiatorConfig,
    fhan,
    fst,
)

__all__ = [
    "DEFAULT_FLESO_W_MIN",
    "DEFAULT_TD_FILTER_FACTOR",
    "DEFAULT_TD_SPEED",
    "FLESO",
    "PAPER_FPDESO_FUZZY",
    "PAPER_FPD_FUZZY",
    "REFERENCE_KINDS",
    "TABLE_1",
    "TABLE_7",
    "ZERO_AREA_FALLBACK",
    "ControlChain",
    "FLESOConfig",
    "FPDConfig",
    "FPDController",
    "FPDESOConfig",
    "FPDESOController",
    "FuzzyPDConfig",
    "FuzzyPDGainSchedule",
    "FuzzyVariable",
    "GaussianMF",
    "JointController",
    "Law",
    "MamdaniBatch",
    "MamdaniSystem",
    "NPDConfig",
    "NPDController",
    "NominalModel",
    "PIDConfig",
    "PIDController",
    "RampHoldReference",
    "Reference",
    "RuleTable",
    "SineReference",
    "StepReference",
    "TrackingDifferentiator",
    "TrackingDifferentiatorConfig",
    "TriangularMF",
    "UnknownLawError",
    "build_chain",
    "centroid",
    "centroid_weights",
    "fhan",
    "fst",
    "gaussian_mf",
    "get_law",
    "law_names",
    "law_table",
    "make_chain",
    "make_controller",
    "make_reference",
    "npd_gain",
    "observer_gains",
    "robust_switch",
    "triangular_mf",
]
