"""Bounded estimation: recovers exact data, names what the data cannot separate, refuses unphysical models."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from identification_synthetic import TRUTH, synthetic_run
from numpy.testing import assert_allclose
from smm_analysis.errors import NotExcitingError, NotPhysicalError
from smm_analysis.identification import (
    PARAMETER_NAMES,
    EstimationSettings,
    fit_of,
    identify,
    parameter_vector,
    prepare_run,
)

from smm_dynamics import SMMParameters


def test_recovers_exact_open_loop_data() -> None:
    prepared = prepare_run("synthetic", *synthetic_run())
    result = identify([prepared], settings=EstimationSettings(bootstrap=40))
    assert_allclose(result.theta, parameter_vector(TRUTH), rtol=2e-3)
    assert result.rank == len(PARAMETER_NAMES)
    assert result.condition_number < 100.0
    assert result.min_mass_eigenvalue > 0.0
    assert result.fits[0].nrmse[0] < 0.01 and result.fits[0].nrmse[1] < 0.01
    assert np.all(result.interval[:, 0] <= result.theta) and np.all(result.theta <= result.interval[:, 1])
    assert np.all(result.standard_error > 0.0)


def test_bounds_keep_friction_non_negative() -> None:
    """A plant without Coulomb friction: the estimate sits at the bound 0 (not a negative value)."""
    frictionless = dataclasses.replace(TRUTH, coulomb_friction=(0.0, 0.0))
    result = identify(
        [prepare_run("synthetic", *synthetic_run(frictionless))], settings=EstimationSettings(bootstrap=20)
    )
    names = list(PARAMETER_NAMES)
    for joint in ("alpha", "beta"):
        value = result.theta[names.index(f"coulomb_friction.{joint}")]
        assert 0.0 <= value < 0.01 * result.largest_torque


def test_validation_fit_of_another_run() -> None:
    prepared = prepare_run("synthetic", *synthetic_run())
    assert max(fit_of(prepared, TRUTH).nrmse) < 0.01
    assert min(fit_of(prepared, SMMParameters()).nrmse) > max(fit_of(prepared, TRUTH).nrmse)


def test_a_run_moving_one_joint_names_the_parameters_it_cannot_separate() -> None:
    prepared = prepare_run("beta only", *synthetic_run(only_beta=True))
    with pytest.raises(NotExcitingError, match=r"I44") as raised:
        identify([prepared], settings=EstimationSettings(bootstrap=20))
    assert "viscous_friction.alpha" in str(raised.value)
    assert "I22" not in str(raised.value).split("(")[0]


def test_an_estimate_with_m_not_positive_definite_is_refused() -> None:
    """I11 > I44 + I55 makes M11(0) = I44 - I11 + I55 negative: no physical SMM has it."""
    unphysical = dataclasses.replace(TRUTH, I11=0.2, I44=0.05, I55=0.05)
    # The torques of such a model along the excitation (inverse dynamics needs no M^-1).
    prepared = prepare_run("unphysical", *synthetic_run(unphysical))
    with pytest.raises(NotPhysicalError, match="not positive definite"):
        identify([prepared], settings=EstimationSettings(bootstrap=20))


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"bootstrap": 5}, "bootstrap"),
        ({"block": 0.0}, "block"),
        ({"seed": -1}, "seed"),
        ({"rank_tolerance": 1.0}, "rank_tolerance"),
        ({"workspace": (1.3, 1.6)}, "workspace"),
    ],
)
def test_invalid_settings_name_the_field(overrides: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=f"^{message}"):
        EstimationSettings(**overrides)  # type: ignore[arg-type]
