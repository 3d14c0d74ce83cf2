"""The offline closed loop for N runs at once (numpy arrays of N), tested against the scalar loop."""

from smm_analysis.batch.loop import (
    INDEX_NAMES,
    SIGN_TOLERANCE,
    SMOOTH_TOLERANCE,
    RunSettings,
    agreement_tolerance,
    indices_of,
    run_batch,
    run_scalar,
    scalar_indices,
)

__all__ = [
    "INDEX_NAMES",
    "SIGN_TOLERANCE",
    "SMOOTH_TOLERANCE",
    "RunSettings",
    "agreement_tolerance",
    "indices_of",
    "run_batch",
    "run_scalar",
    "scalar_indices",
]
