"""The batched closed loop equals the scalar loop run by run, whatever the grouping (smm_analysis.batch)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_analysis.batch import (
    INDEX_NAMES,
    SIGN_TOLERANCE,
    SMOOTH_TOLERANCE,
    RunSettings,
    run_batch,
    scalar_indices,
)
from smm_analysis.batch.fuzzy import BandwidthFuzzy, PDGainFuzzy
from smm_analysis.errors import AnalysisError
from smm_analysis.scenarios import get_scenario
from smm_controller.fuzzy_batch import MamdaniBatch
from smm_controller.fuzzy_pd import PAPER_FPD_FUZZY, FuzzyPDConfig
from smm_controller.laws import PAPER_LAWS
from smm_controller.limits import OutputLimitConfig
from smm_controller.rules import TABLE_1, TABLE_7, fleso_bandwidth_system, pd_gain_system
from smm_sim.plant import PlantConfig

from smm_controller import (
    FLESOConfig,
    FPDConfig,
    FPDESOConfig,
    NPDConfig,
    PIDConfig,
    TrackingDifferentiatorConfig,
)
from smm_dynamics import SMMParameters


def _close(batch: dict[str, float], scalar: dict[str, float], tolerance: float) -> None:
    for name in INDEX_NAMES:
        expected, got = scalar[name], batch[name]
        if math.isnan(expected):
            assert math.isnan(got), name
        else:
            assert got == pytest.approx(expected, rel=tolerance, abs=1e-12), name


def _pair(low: float, high: float) -> st.SearchStrategy[tuple[float, float]]:
    return st.tuples(st.floats(low, high), st.floats(low, high))


_SCENARIOS = st.sampled_from(["step", "case1", "case2"]).map(
    lambda name: get_scenario(name).with_duration(0.12)
)


@st.composite
def _plants(draw: st.DrawFn) -> PlantConfig:
    params = SMMParameters(
        I11=draw(st.floats(0.05, 0.09)),
        viscous_friction=draw(_pair(0.0, 0.3)),
        coulomb_friction=draw(st.sampled_from([(0.0, 0.0), (0.2, 0.1)])),
        torque_offset=draw(st.sampled_from([(0.0, 0.0), (0.05, -0.1)])),
        mass_lever=draw(st.floats(0.0, 0.05)),
    )
    return PlantConfig(
        params=params,
        inertia_scale=draw(st.floats(0.8, 1.2)),
        noise_std=draw(st.sampled_from([(0.0, 0.0), (0.001, 0.001), (0.0005, 0.002)])),
        encoder_counts_per_rev=draw(st.sampled_from([0, 4096])),
        seed=draw(st.integers(0, 2**31)),
        disturbance=draw(st.sampled_from(["none", "eq46"])),
        joint_limits=draw(st.sampled_from([(1.3, 1.3), (0.5, 0.4)])),
        torque_limit=draw(st.sampled_from([(math.inf, math.inf), (40.0, 30.0)])),
        torque_quantum=draw(st.sampled_from([(0.0, 0.0), (0.01, 0.02)])),
        valve_time_constants=draw(st.sampled_from([None, (0.0217, 0.0109)])),
    )


@st.composite
def _fuzzy(draw: st.DrawFn, base: FuzzyPDConfig) -> FuzzyPDConfig:
    scale = draw(st.floats(1.0, 1.3))
    return dataclasses.replace(
        base,
        k_e=draw(_pair(0.5, 8.0)),
        k_de=draw(_pair(0.5, 8.0)),
        kp0=(base.kp0[0] * scale, base.kp0[1] * scale),
        kd0=(base.kd0[0] * scale, base.kd0[1] * scale),
    )


@st.composite
def _settings(draw: st.DrawFn, controller: str, smooth: bool = True) -> RunSettings:
    scenario = draw(_SCENARIOS)
    compensate = controller == "fpdeso" and draw(st.booleans())  # the feedforward's and observer's F together
    law: FPDESOConfig | FPDConfig | PIDConfig | NPDConfig
    if controller == "fpdeso":
        law = FPDESOConfig(
            fuzzy=draw(_fuzzy(FuzzyPDConfig())),
            robust_gain=draw(_pair(0.0, 0.5)),
            boundary_layer=draw(_pair(0.01, 1.0)) if smooth else (0.0, 0.0),
            velocity_source=draw(st.sampled_from(["td", "observer"])),
            compensate_friction=compensate,
        )
    elif controller == "fpd":
        law = FPDConfig(fuzzy=draw(_fuzzy(PAPER_FPD_FUZZY)))
    elif controller == "pid":
        law = PIDConfig(
            kp=draw(_pair(5.0, 60.0)),
            ki=draw(_pair(0.0, 5.0)),
            kd=draw(_pair(0.0, 2.0)),
            integrator_limit=draw(st.sampled_from([(math.inf, math.inf), (0.5, 0.5)])),
            output_limit=draw(st.sampled_from([(math.inf, math.inf), (20.0, 20.0)])),
        )
    else:
        law = NPDConfig(
            k_np=draw(_pair(10.0, 40.0)), rho_p=draw(_pair(0.6, 1.4)), rho_d=draw(_pair(0.6, 1.4))
        )
    return RunSettings(
        scenario=scenario,
        controller=controller,
        law=law,
        plant=draw(_plants()),
        td=TrackingDifferentiatorConfig(filter_factor=draw(_pair(0.001, 0.005)), speed=draw(_pair(1e4, 1e6))),
        fleso=FLESOConfig(
            w0=draw(_pair(10.0, 40.0)), k_w=draw(_pair(0.0, 15.0)), compensate_friction=compensate
        ),
        model=SMMParameters(
            I11=draw(st.floats(0.05, 0.09)),
            coulomb_friction=draw(st.sampled_from([(0.0, 0.0), (0.15, 0.05)])),
            torque_offset=draw(st.sampled_from([(0.0, 0.0), (-0.02, 0.04)])),
        ),
        output=OutputLimitConfig(
            torque_limit=draw(st.sampled_from([(300.0, 300.0), (25.0, 20.0)])),
            rate_limit=draw(st.sampled_from([(math.inf, math.inf), (20000.0, 20000.0)])),
        ),
    )


@pytest.mark.parametrize("controller", PAPER_LAWS)
@settings(max_examples=12)
@given(data=st.data())
def test_every_run_of_a_batch_equals_the_scalar_loop(controller: str, data: st.DataObject) -> None:
    runs = data.draw(st.lists(_settings(controller), min_size=1, max_size=3))
    for batch, run in zip(run_batch(runs), runs, strict=True):
        _close(batch, scalar_indices(run), SMOOTH_TOLERANCE)


@settings(max_examples=6)
@given(runs=st.lists(_settings("fpdeso", smooth=False), min_size=1, max_size=3))
def test_with_the_pure_sign_every_run_equals_the_scalar_loop_within_the_stated_tolerance(
    runs: list[RunSettings],
) -> None:
    for batch, run in zip(run_batch(runs), runs, strict=True):
        _close(batch, scalar_indices(run), SIGN_TOLERANCE)


@settings(max_examples=5)
@given(runs=st.lists(_settings("fpdeso", smooth=False), min_size=2, max_size=5), cut=st.integers(1, 4))
def test_results_do_not_depend_on_how_runs_are_grouped(runs: list[RunSettings], cut: int) -> None:
    whole = run_batch(runs)
    parts = run_batch(runs[:cut]) + run_batch(runs[cut:]) + run_batch(runs[:1])
    assert parts[: len(runs)] == whole or np.array_equal(
        np.array([[r[k] for k in INDEX_NAMES] for r in parts[: len(runs)]]),
        np.array([[r[k] for k in INDEX_NAMES] for r in whole]),
        equal_nan=True,
    )
    assert np.array_equal(
        np.array([parts[-1][k] for k in INDEX_NAMES]),
        np.array([whole[0][k] for k in INDEX_NAMES]),
        equal_nan=True,
    )


def test_a_diverging_run_is_nan_and_the_others_still_equal_the_scalar_loop() -> None:
    scenario = get_scenario("step").with_duration(0.3)
    plant = PlantConfig()
    unbounded = OutputLimitConfig(torque_limit=(math.inf, math.inf))
    good = RunSettings(scenario, "pid", PIDConfig(), plant, output=unbounded)
    bad = RunSettings(scenario, "pid", PIDConfig(kp=(1e9, 1e9)), plant, output=unbounded)
    batch = run_batch([good, bad, good])
    assert all(math.isnan(batch[1][name]) for name in INDEX_NAMES)
    assert all(math.isnan(value) for value in scalar_indices(bad).values())
    _close(batch[0], scalar_indices(good), SMOOTH_TOLERANCE)
    assert batch[0] == batch[2]


def test_a_batch_refuses_runs_of_different_length_or_controller() -> None:
    plant = PlantConfig()
    step = get_scenario("step")
    with pytest.raises(AnalysisError, match="same control period, duration and controller"):
        run_batch(
            [
                RunSettings(step, "npd", NPDConfig(), plant),
                RunSettings(step.with_duration(0.5), "npd", NPDConfig(), plant),
            ]
        )
    with pytest.raises(AnalysisError, match="same control period, duration and controller"):
        run_batch(
            [RunSettings(step, "npd", NPDConfig(), plant), RunSettings(step, "pid", PIDConfig(), plant)]
        )
    with pytest.raises(AnalysisError, match="needs a FPDESOConfig"):
        RunSettings(step, "fpdeso", NPDConfig(), plant)


@settings(max_examples=50)
@given(
    x=st.lists(
        st.floats(-1.0, 1.0) | st.sampled_from([-1.0, -2 / 3, 0.0, 1 / 3, 1.0]), min_size=4, max_size=4
    ),
    s=st.lists(st.floats(-1.0, 1.0) | st.sampled_from([-1.0, -0.5, 0.0, 1.0]), min_size=2, max_size=2),
)
def test_fuzzy_centroids_equal_the_scalar_engine(x: list[float], s: list[float]) -> None:
    pd = MamdaniBatch([pd_gain_system(TABLE_1), pd_gain_system(TABLE_7)])
    f_ke, f_kde = PDGainFuzzy(201).evaluate(np.array([[x[0], x[1]]]), np.array([[x[2], x[3]]]))
    expected = pd.evaluate_flat(((x[0], x[2]), (x[1], x[3])))
    assert [f_ke[0, 0], f_kde[0, 0], f_ke[0, 1], f_kde[0, 1]] == pytest.approx(expected, rel=1e-12, abs=1e-13)
    bandwidth = MamdaniBatch([fleso_bandwidth_system(201)] * 2)
    got = BandwidthFuzzy(201).evaluate(np.array([s]))
    assert list(got[0]) == pytest.approx(bandwidth.evaluate_flat(((s[0],), (s[1],))), rel=1e-12, abs=1e-13)
