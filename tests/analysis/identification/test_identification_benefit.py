"""The loop closes: case 2 with the model identified from the excite run tracks better than the nominal."""

from __future__ import annotations

import numpy as np
import pytest
from smm_analysis.identification.benefit import compare_models, identified_case2_model

from smm_dynamics import SMMParameters


@pytest.mark.slow
def test_identified_model_tracks_case2_better_and_leaves_less_to_the_observer() -> None:
    identified = identified_case2_model(seed=0)
    truth = SMMParameters().with_inertia_scale(1.1)
    assert abs(identified.I22 / truth.I22 - 1.0) < 0.05
    nominal, plain, compensated = compare_models(identified, seed=0)
    # RMS tracking error, both joints, same seed and plant.
    assert np.all(plain.tracking_rms < nominal.tracking_rms)
    assert np.all(compensated.tracking_rms < nominal.tracking_rms)
    # The model-error part of the lumped disturbance shrinks, and with the friction in the model the
    # observer's estimate does too.
    assert np.all(plain.model_error_rms < nominal.model_error_rms)
    assert np.all(compensated.model_error_rms < 0.1 * nominal.model_error_rms)
    assert np.all(compensated.estimate_rms < nominal.estimate_rms)
    assert np.all(plain.estimate_rms <= nominal.estimate_rms)
