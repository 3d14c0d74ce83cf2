"""The excitation's quality: a well-conditioned regressor over the default design, a poor one over a sine."""

from __future__ import annotations

import numpy as np
from smm_analysis.identification.excitation import excitation_quality
from smm_controller.excitation import ExcitationReference


def test_default_excitation_is_well_conditioned_and_reports_its_crest_factor() -> None:
    quality = excitation_quality(ExcitationReference())
    assert 1.0 <= quality.condition_number < 100.0
    assert quality.crest_factor == ExcitationReference().crest_factor()


def test_a_narrow_excitation_is_worse_conditioned() -> None:
    narrow = ExcitationReference(position_limit=(0.05, 0.05), velocity_limit=(0.1, 0.1))
    assert (
        excitation_quality(narrow).condition_number
        > excitation_quality(ExcitationReference()).condition_number
    )
    assert np.isfinite(excitation_quality(narrow).condition_number)
