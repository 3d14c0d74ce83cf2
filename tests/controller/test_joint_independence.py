"""Per-joint maths depends only on its own joint (issue #16).

Two properties wherever a quantity is computed per joint:

* swap: swapping the joints' inputs and per-joint configs (and rule tables) swaps the outputs;
* isolation: changing one joint's input history leaves the other joint's per-joint quantities unchanged.

Together they catch a beta quantity computed from alpha's state or config (docs/TESTING.md shows the
planted mutant these tests fail on). Laws without fuzzy rules agree bit for bit. Where the fuzzy rule
base is evaluated, the joints' four-rule cells are clipped and defuzzified in one numpy pass whose dot
product rounds differently with one or two rows, so those agree to rounding (1e-12 rel., 1e-15 abs.).
The FLESO couples the joints through the model (M^-1 in eq. 21) by design, so its per-joint quantities
(innovation E, its rate E', fuzzy input s, bandwidth w, that joint's corrected states) are checked at the
step where the other joint's measurement differs, and the swap at the first innovation, which the model
does not enter.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from smm_controller.baselines import (
    FPDConfig,
    FPDController,
    NPDConfig,
    NPDController,
    PIDConfig,
    PIDController,
)
from smm_controller.fleso import FLESO, FLESOConfig
from smm_controller.fpdeso import FPDESOConfig, FPDESOController
from smm_controller.fuzzy_pd import PAPER_FPD_FUZZY, FuzzyPDConfig, FuzzyPDGainSchedule
from smm_controller.reference import RampHoldReference, SineReference, StepReference
from smm_controller.rules import TABLE_1, TABLE_7
from smm_controller.td import TrackingDifferentiator, TrackingDifferentiatorConfig

from smm_dynamics import SMMParameters

DT = 0.001
PARAMS = SMMParameters()
C = TypeVar("C")

positions = st.floats(-0.6, 0.6, allow_nan=False, allow_subnormal=True)
rates = st.floats(-3.0, 3.0, allow_nan=False, allow_subnormal=True)
histories = st.lists(st.tuples(positions, positions, rates, rates), min_size=1, max_size=12)


def positive(low: float, high: float) -> st.SearchStrategy[tuple[float, float]]:
    return st.tuples(*[st.floats(low, high, allow_nan=False, allow_subnormal=False)] * 2)


def swapped(value: C) -> C:
    """The config with every per-joint pair (also in nested configs) in the other order."""
    changes: dict[str, Any] = {}
    for field in dataclasses.fields(value):  # type: ignore[arg-type]
        item = getattr(value, field.name)
        if isinstance(item, tuple) and len(item) == 2:
            changes[field.name] = (item[1], item[0])
        elif dataclasses.is_dataclass(item):
            changes[field.name] = swapped(item)
    return dataclasses.replace(value, **changes)  # type: ignore[type-var]


def agree(first: Any, second: Any) -> bool:
    """Equal to rounding: nested dicts/sequences of floats, 1e-12 relative, 1e-15 absolute."""
    if isinstance(first, Mapping):
        return first.keys() == second.keys() and all(agree(first[k], second[k]) for k in first)
    if isinstance(first, (list, tuple, np.ndarray)):
        return len(first) == len(second) and all(agree(a, b) for a, b in zip(first, second, strict=True))
    return math.isclose(first, second, rel_tol=1e-12, abs_tol=1e-15)


def flipped(pairs: Mapping[str, Any]) -> dict[str, list[float]]:
    return {key: list(np.asarray(value)[::-1]) for key, value in pairs.items()}


def listed(pairs: Mapping[str, Any]) -> dict[str, list[float]]:
    return {key: list(np.asarray(value)) for key, value in pairs.items()}


def alpha_of(pairs: Mapping[str, Any], keys: Sequence[str] | None = None) -> dict[str, float]:
    return {key: float(np.asarray(value)[0]) for key, value in pairs.items() if keys is None or key in keys}


def reference_rows(sample: tuple[float, float, float, float]) -> list[list[float]]:
    a, b, ad, bd = sample
    return [[a, b], [ad, bd], [0.5 * ad, -0.5 * bd]]


def swap_rows(rows: Sequence[Sequence[float]]) -> list[list[float]]:
    return [[row[1], row[0]] for row in rows]


def beta_changed(history: list[tuple[float, float, float, float]], shift: float) -> list[Any]:
    return [(a, b + shift * (k + 1), ad, bd - shift) for k, (a, b, ad, bd) in enumerate(history)]


# Tracking differentiator --------------------------------------------------------------------------------

td_configs = st.builds(
    TrackingDifferentiatorConfig, speed=positive(10.0, 1e6), filter_factor=positive(DT, 0.01)
)


@settings(max_examples=60)
@given(config=td_configs, history=histories)
def test_td_swap(config: TrackingDifferentiatorConfig, history: list[Any]) -> None:
    straight, mirrored = TrackingDifferentiator(config), TrackingDifferentiator(swapped(config))
    for a, b, _, _ in history:
        x1, x2 = straight.step([a, b], DT)
        y1, y2 = mirrored.step([b, a], DT)
        assert list(y1) == list(x1[::-1]) and list(y2) == list(x2[::-1])
        assert listed(mirrored.internals) == flipped(straight.internals)


@settings(max_examples=60)
@given(config=td_configs, history=histories, shift=st.floats(0.01, 0.5, allow_subnormal=False))
def test_td_alpha_ignores_beta_history(
    config: TrackingDifferentiatorConfig, history: list[Any], shift: float
) -> None:
    first, second = TrackingDifferentiator(config), TrackingDifferentiator(config)
    for (a, b, _, _), (a2, b2, _, _) in zip(history, beta_changed(history, shift), strict=True):
        x1, x2 = first.step([a, b], DT)
        y1, y2 = second.step([a2, b2], DT)
        assert (y1[0], y2[0]) == (x1[0], x2[0])
        assert alpha_of(second.internals) == alpha_of(first.internals)


# Fuzzy PD gain schedule ----------------------------------------------------------------------------------

fuzzy_configs = st.builds(
    FuzzyPDConfig,
    k_e=positive(0.5, 10.0),
    k_de=positive(0.5, 10.0),
    k1=positive(0.0, 5.0),
    k2=positive(0.0, 1.0),
    kp0=positive(10.0, 100.0),
    kd0=positive(2.0, 10.0),
    grid_points=st.sampled_from([51, 201]),
)


@settings(max_examples=40)
@given(config=fuzzy_configs, history=histories)
def test_fuzzy_schedule_swap(config: FuzzyPDConfig, history: list[Any]) -> None:
    straight = FuzzyPDGainSchedule(config, (TABLE_1, TABLE_7))
    mirrored = FuzzyPDGainSchedule(swapped(config), (TABLE_7, TABLE_1))
    for a, b, ad, bd in history:
        kp, kd = straight.step([a, b], [ad, bd])
        kp_m, kd_m = mirrored.step([b, a], [bd, ad])
        assert agree([kp_m, kd_m], [kp[::-1], kd[::-1]])
        assert agree(listed(mirrored.internals), flipped(straight.internals))


@settings(max_examples=40)
@given(config=fuzzy_configs, history=histories, shift=st.floats(0.01, 0.5, allow_subnormal=False))
def test_fuzzy_schedule_alpha_ignores_beta(config: FuzzyPDConfig, history: list[Any], shift: float) -> None:
    first, second = FuzzyPDGainSchedule(config), FuzzyPDGainSchedule(config)
    for (a, b, ad, bd), (_, b2, _, bd2) in zip(history, beta_changed(history, shift), strict=True):
        kp, kd = first.step([a, b], [ad, bd])
        kp2, kd2 = second.step([a, b2], [ad, bd2])
        assert agree((kp2[0], kd2[0]), (kp[0], kd[0]))
        assert agree(alpha_of(second.internals), alpha_of(first.internals))


# Baselines and the FPDESO law ------------------------------------------------------------------------------

pid_configs = st.builds(
    PIDConfig,
    kp=positive(0.0, 50.0),
    ki=positive(0.0, 5.0),
    kd=positive(0.0, 2.0),
    derivative_filter=positive(10.0, 2000.0),
    integrator_limit=positive(0.001, 1.0),
    output_limit=positive(0.5, 20.0),
)
npd_configs = st.builds(
    NPDConfig,
    k_np=positive(1.0, 30.0),
    k_nd=positive(0.1, 1.0),
    delta_p=positive(0.01, 0.3),
    delta_d=positive(0.01, 0.3),
    rho_p=positive(0.5, 1.5),
    rho_d=positive(0.5, 1.5),
)
fpdeso_configs = st.builds(
    FPDESOConfig,
    fuzzy=fuzzy_configs,
    robust_gain=positive(0.0, 0.2),
    boundary_layer=positive(0.0, 1.0),
)


def pid(config: Any) -> PIDController:
    return PIDController(config)


def npd(config: Any) -> NPDController:
    return NPDController(config)


def fpd(config: Any, tables: tuple[Any, Any] = (TABLE_1, TABLE_7)) -> FPDController:
    controller = FPDController(FPDConfig(config))
    controller.schedule = FuzzyPDGainSchedule(config, tables)  # the FPD law's own schedule, tables chosen
    controller.reset()
    return controller


LAWS: dict[str, tuple[Callable[..., Any], st.SearchStrategy[Any]]] = {
    "pid": (pid, pid_configs),
    "npd": (npd, npd_configs),
    "fpd": (fpd, st.one_of(st.just(PAPER_FPD_FUZZY), fuzzy_configs)),
}


def run_law(
    controller: Any, rows: list[list[float]], q: Sequence[float], q_dot: Sequence[float]
) -> list[float]:
    return list(controller.step(np.array(rows), np.array(q), np.array(q_dot), np.zeros(2), DT))


@settings(max_examples=40)
@given(data=st.data(), law=st.sampled_from(sorted(LAWS)), history=histories)
def test_baseline_swap(data: st.DataObject, law: str, history: list[Any]) -> None:
    make, configs = LAWS[law]
    config = data.draw(configs)
    straight = make(config)
    mirrored = make(swapped(config), (TABLE_7, TABLE_1)) if law == "fpd" else make(swapped(config))
    for sample in history:
        rows = reference_rows(sample)
        q, q_dot = (0.1 * sample[1], -0.2 * sample[0]), (sample[3], 0.3)
        tau = run_law(straight, rows, q, q_dot)
        tau_m = run_law(mirrored, swap_rows(rows), q[::-1], q_dot[::-1])
        exact = law != "fpd"
        assert tau_m == tau[::-1] if exact else agree(tau_m, tau[::-1])
        assert (
            (listed(mirrored.internals) == flipped(straight.internals))
            if exact
            else agree(listed(mirrored.internals), flipped(straight.internals))
        )


@settings(max_examples=40)
@given(
    data=st.data(),
    law=st.sampled_from(sorted(LAWS)),
    history=histories,
    shift=st.floats(0.01, 0.5, allow_subnormal=False),
)
def test_baseline_alpha_ignores_beta_history(
    data: st.DataObject, law: str, history: list[Any], shift: float
) -> None:
    make, configs = LAWS[law]
    config = data.draw(configs)
    first, second = make(config), make(config)
    for sample, changed in zip(history, beta_changed(history, shift), strict=True):
        q_dot = (0.2, sample[2])
        tau = run_law(first, reference_rows(sample), (0.05, 0.1), q_dot)
        tau2 = run_law(second, reference_rows(changed), (0.05, -0.3), (0.2, -sample[2]))
        exact = law != "fpd"
        assert tau2[0] == tau[0] if exact else agree(tau2[0], tau[0])
        assert (
            (alpha_of(second.internals) == alpha_of(first.internals))
            if exact
            else agree(alpha_of(second.internals), alpha_of(first.internals))
        )


@settings(max_examples=40)
@given(config=fpdeso_configs, history=histories, shift=st.floats(0.01, 0.5, allow_subnormal=False))
def test_fpdeso_pd_terms_alpha_ignores_beta(config: FPDESOConfig, history: list[Any], shift: float) -> None:
    """kp, kd and u (eq. 11-12) are per joint; the model terms couple the joints by design."""
    first, second = FPDESOController(config, PARAMS), FPDESOController(config, PARAMS)
    keys = ("kp", "kd", "u")
    for sample, changed in zip(history, beta_changed(history, shift), strict=True):
        run_law(first, reference_rows(sample), (0.1, 0.2), (0.0, 0.1))
        run_law(second, reference_rows(changed), (0.1, -0.2), (0.0, 0.4))
        assert agree(alpha_of(second.internals, keys), alpha_of(first.internals, keys))


# FLESO: per-joint innovation, its rate, fuzzy input and bandwidth ----------------------------------------

fleso_configs = st.builds(
    FLESOConfig,
    w0=positive(5.0, 40.0),
    k_w=positive(0.0, 20.0),
    k_s1=positive(0.0, 10.0),
    k_s2=positive(0.0, 2.0),
    w_min=positive(1.0, 30.0),
    grid_points=st.sampled_from([51, 201]),
)
PER_JOINT_FLESO = ("estimation_error", "estimation_error_rate", "fuzzy_input", "bandwidth")
small = st.floats(-0.01, 0.01, allow_nan=False, allow_subnormal=True)


@settings(max_examples=60)
@given(config=fleso_configs, y=st.tuples(small, small), start=st.tuples(small, small))
def test_fleso_swap_at_the_first_innovation(
    config: FLESOConfig, y: tuple[float, float], start: tuple[float, float]
) -> None:
    straight, mirrored = FLESO(config, PARAMS), FLESO(swapped(config), PARAMS)
    straight.step(list(start), [0.0, 0.0], DT)
    mirrored.step(list(start[::-1]), [0.0, 0.0], DT)
    straight.step(list(y), [0.0, 0.0], DT)
    mirrored.step(list(y[::-1]), [0.0, 0.0], DT)
    for key in (*PER_JOINT_FLESO, "x1_hat"):
        assert agree(list(mirrored.internals[key]), list(straight.internals[key][::-1])), key


@settings(max_examples=60)
@given(config=fleso_configs, history=histories, shift=st.floats(0.001, 0.05, allow_subnormal=False))
def test_fleso_alpha_ignores_beta_input_at_that_step(
    config: FLESOConfig, history: list[Any], shift: float
) -> None:
    """Same past, beta's measurement differs at step k: alpha's per-joint quantities do not.

    (The torque is kept: it enters the prediction through M^-1, which couples the joints by design.)
    """
    first, second = FLESO(config, PARAMS), FLESO(config, PARAMS)
    for a, b, ad, bd in history[:-1]:
        for observer in (first, second):
            observer.step([0.1 * a, 0.1 * b], [ad, bd], DT)
    a, b, ad, bd = history[-1]
    first.step([0.1 * a, 0.1 * b], [ad, bd], DT)
    second.step([0.1 * a, 0.1 * b + shift], [ad, bd], DT)
    keys = (*PER_JOINT_FLESO, "x1_hat", "x2_hat", "x3_hat")
    assert agree(alpha_of(second.internals, keys), alpha_of(first.internals, keys))


# Reference generators ------------------------------------------------------------------------------------

pairs = st.tuples(positions, positions)
references = st.one_of(
    st.builds(StepReference, amplitude=pairs, start_time=st.floats(0.0, 1.0, allow_subnormal=True)),
    st.builds(
        SineReference,
        amplitude=pairs,
        angular_frequency=st.floats(0.5, 10.0, allow_subnormal=False),
        phase=pairs,
    ),
    st.builds(
        RampHoldReference,
        target=pairs,
        ramp_time=st.floats(0.1, 2.0, allow_subnormal=False),
        start_time=st.floats(0.0, 1.0, allow_subnormal=True),
        initial=pairs,
        profile=st.sampled_from(["linear", "quintic"]),
    ),
)


@settings(max_examples=60)
@given(reference=references, t=st.floats(0.0, 3.0, allow_subnormal=True))
def test_reference_swap(reference: Any, t: float) -> None:
    rows = reference.rows(t)
    assert swapped(reference).rows(t) == tuple((b, a) for a, b in rows)
