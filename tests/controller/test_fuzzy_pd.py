"""Fuzzy PD gain schedule (eq. 12)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from smm_controller.fuzzy_batch import evaluate_system
from smm_controller.fuzzy_pd import PAPER_FPD_FUZZY, PAPER_FPDESO_FUZZY, FuzzyPDConfig, FuzzyPDGainSchedule
from smm_controller.rules import TABLE_1, TABLE_7, pd_gain_system

signals = st.floats(-3.0, 3.0, allow_subnormal=True)


@settings(deadline=None, max_examples=60)
@given(e0=signals, e1=signals, ed0=signals, ed1=signals)
def test_gains_follow_eq_12(e0: float, e1: float, ed0: float, ed1: float) -> None:
    config = PAPER_FPDESO_FUZZY
    kp, kd = FuzzyPDGainSchedule(config).step([e0, e1], [ed0, ed1])
    for j, (table, e, ed) in enumerate(((TABLE_1, e0, ed0), (TABLE_7, e1, ed1))):
        e_n = float(np.clip(config.k_e[j] * e, -1, 1))
        ce_n = float(np.clip(config.k_de[j] * ed, -1, 1))
        f_ke, f_kde = evaluate_system(pd_gain_system(table), (e_n, ce_n))
        assert kp[j] == pytest.approx(config.kp0[j] + config.k1[j] * f_ke, rel=1e-13)
        assert kd[j] == pytest.approx(config.kd0[j] + config.k2[j] * f_kde, rel=1e-13)


def test_inputs_are_clipped_to_the_unit_interval() -> None:
    schedule = FuzzyPDGainSchedule(PAPER_FPD_FUZZY)
    saturated = schedule.step([10.0, -10.0], [10.0, -10.0])
    edge = schedule.step(
        [1.0 / PAPER_FPD_FUZZY.k_e[0], -1.0 / PAPER_FPD_FUZZY.k_e[1]],
        [1.0 / PAPER_FPD_FUZZY.k_de[0], -1.0 / PAPER_FPD_FUZZY.k_de[1]],
    )
    assert_allclose(saturated, edge, rtol=1e-14)
    assert_allclose(schedule.internals["e_normalised"], [1.0, -1.0])


def test_gains_stay_within_the_fuzzy_range() -> None:
    schedule = FuzzyPDGainSchedule()
    rng = np.random.default_rng(3)
    config = PAPER_FPDESO_FUZZY
    for _ in range(200):
        kp, kd = schedule.step(rng.normal(0, 0.5, 2), rng.normal(0, 0.5, 2))
        assert np.all(np.abs(kp - np.array(config.kp0)) < np.array(config.k1))
        assert np.all(np.abs(kd - np.array(config.kd0)) < np.array(config.k2))


def test_internals_record_the_last_step() -> None:
    schedule = FuzzyPDGainSchedule()
    kp, kd = schedule.step([0.1, -0.05], [0.02, 0.3])
    internals = schedule.internals
    assert_allclose(internals["kp"], kp)
    assert_allclose(internals["kd"], kd)
    config = PAPER_FPDESO_FUZZY
    assert_allclose(kp, np.array(config.kp0) + np.array(config.k1) * internals["f_ke"])
    assert set(internals) == {"e_normalised", "ce_normalised", "f_ke", "f_kde", "kp", "kd"}


def test_grid_points_change_the_defuzzification_grid() -> None:
    coarse = FuzzyPDGainSchedule(FuzzyPDConfig(grid_points=5)).step([0.1, 0.1], [0.05, 0.05])
    fine = FuzzyPDGainSchedule(FuzzyPDConfig(grid_points=101)).step([0.1, 0.1], [0.05, 0.05])
    assert not np.allclose(coarse[0], fine[0], rtol=0, atol=1e-6)


def test_shape_checks() -> None:
    with pytest.raises(ValueError, match="e must have shape"):
        FuzzyPDGainSchedule().step([0.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="e_dot must be finite"):
        FuzzyPDGainSchedule().step([0.0, 0.0], [np.inf, 0.0])
