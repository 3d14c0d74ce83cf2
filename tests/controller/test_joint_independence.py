"""Per-joint maths depends only on its own joint (issue #16).

Two properties wherever a quantity is computed per joint:

* swap: swapping the joints' inputs and per-joint configs (and rule tables) swaps the outputs;
* isolation: changing one joint's input history leaves the other joint's per-joint quantities unchanged.

Together they catch a beta quantity computed from alpha's state or config (docs/TESTING.md shows the
planted mutant these tests fail on). Laws without fuzzy rules agree bit for bit. Where the fuzzy rule
base is evaluated, the joints' four-rule cells are clipped and defuzzified in one numpy pass whose dot
product rounds differently with one or two rows, so those agree to rounding (1e-12 rel., 1e-15 abs.).
The FLESO and the FPDESO law couple the joints only through the nominal model (M, C, G); given a
decoupled model (``DecoupledModel``, each joint's terms from its own coordinates) both must be two
independent per-joint algorithms, which the same two properties check over whole histories.
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


def joint_of(pairs: Mapping[str, Any], joint: int) -> dict[str, float]:
    return {key: float(np.asarray(value)[joint]) for key, value in pairs.items()}


def reference_rows(sample: tuple[float, float, float, float]) -> list[list[float]]:
    a, b, ad, bd = sample
    return [[a, b], [ad, bd], [0.5 * ad, -0.5 * bd]]


def swap_rows(rows: Sequence[Sequence[float]]) -> list[list[float]]:
    return [[row[1], row[0]] for row in rows]


def changed(history: list[tuple[float, float, float, float]], joint: int, shift: float) -> list[Any]:
    """The history with the given joint's position and rate moved (by a different amount each step)."""
    moved = []
    for k, (a, b, ad, bd) in enumerate(history):
        if joint == 0:
            moved.append((a + shift * (k + 1), b, ad - shift, bd))
        else:
            moved.append((a, b + shift * (k + 1), ad, bd - shift))
    return moved


shifts = st.floats(0.01, 0.5, allow_subnormal=False)
joints = st.sampled_from([0, 1])


class DecoupledModel:
    """A nominal model whose M is diagonal and whose terms for joint j depend on joint j only."""

    def __init__(
        self, inertia: tuple[float, float], friction: tuple[float, float], gravity: tuple[float, float]
    ) -> None:
        self.inertia, self.friction, self.gravity = inertia, friction, gravity

    def swapped(self) -> DecoupledModel:
        return DecoupledModel(self.inertia[::-1], self.friction[::-1], self.gravity[::-1])

    def mass(self, alpha: float, beta: float) -> tuple[float, float, float]:
        return self.inertia[0] * (1.0 + 0.1 * alpha * alpha), 0.0, self.inertia[1] * (1.0 + 0.1 * beta * beta)

    def bias(
        self, alpha: float, beta: float, alpha_dot: float, beta_dot: float
    ) -> tuple[float, float, float, float, float, float, float]:
        m11, m12, m22 = self.mass(alpha, beta)
        c0, c1 = self.friction[0] * alpha_dot * abs(alpha_dot), self.friction[1] * beta_dot * abs(beta_dot)
        return m11, m12, m22, c0, c1, self.gravity[0] * math.sin(alpha), self.gravity[1] * math.sin(beta)


decoupled_models = st.builds(
    DecoupledModel, inertia=positive(0.05, 0.5), friction=positive(0.0, 0.2), gravity=positive(0.0, 0.5)
)


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
@given(config=td_configs, history=histories, joint=joints, shift=shifts)
def test_td_joint_ignores_the_other_history(
    config: TrackingDifferentiatorConfig, history: list[Any], joint: int, shift: float
) -> None:
    first, second = TrackingDifferentiator(config), TrackingDifferentiator(config)
    for (a, b, _, _), (a2, b2, _, _) in zip(history, changed(history, 1 - joint, shift), strict=True):
        x1, x2 = first.step([a, b], DT)
        y1, y2 = second.step([a2, b2], DT)
        assert (y1[joint], y2[joint]) == (x1[joint], x2[joint])
        assert joint_of(second.internals, joint) == joint_of(first.internals, joint)


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
@given(config=fuzzy_configs, history=histories, joint=joints, shift=shifts)
def test_fuzzy_schedule_joint_ignores_the_other(
    config: FuzzyPDConfig, history: list[Any], joint: int, shift: float
) -> None:
    first, second = FuzzyPDGainSchedule(config), FuzzyPDGainSchedule(config)
    for (a, b, ad, bd), (a2, b2, ad2, bd2) in zip(history, changed(history, 1 - joint, shift), strict=True):
        kp, kd = first.step([a, b], [ad, bd])
        kp2, kd2 = second.step([a2, b2], [ad2, bd2])
        assert agree((kp2[joint], kd2[joint]), (kp[joint], kd[joint]))
        assert agree(joint_of(second.internals, joint), joint_of(first.internals, joint))


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
    boundary_layer=st.one_of(st.just((0.0, 0.0)), positive(0.0, 1.0)),
)


def pid(config: Any, model: DecoupledModel, mirrored: bool) -> PIDController:
    return PIDController(config)


def npd(config: Any, model: DecoupledModel, mirrored: bool) -> NPDController:
    return NPDController(config)


def fpd(config: Any, model: DecoupledModel, mirrored: bool) -> FPDController:
    controller = FPDController(FPDConfig(config))
    if mirrored:  # beta's rule table on alpha and vice versa
        controller.schedule = FuzzyPDGainSchedule(config, (TABLE_7, TABLE_1))
    return controller


def fpdeso(config: Any, model: DecoupledModel, mirrored: bool) -> FPDESOController:
    controller = FPDESOController(config, PARAMS)
    controller.model = model  # type: ignore[assignment]
    if mirrored:
        controller.schedule = FuzzyPDGainSchedule(config.fuzzy, (TABLE_7, TABLE_1))
    return controller


# name: (factory, config strategy, bit for bit)
LAWS: dict[str, tuple[Callable[..., Any], st.SearchStrategy[Any], bool]] = {
    "pid": (pid, pid_configs, True),
    "npd": (npd, npd_configs, True),
    "fpd": (fpd, st.one_of(st.just(PAPER_FPD_FUZZY), fuzzy_configs), False),
    "fpdeso": (fpdeso, fpdeso_configs, False),
}
MODEL = DecoupledModel((0.1, 0.3), (0.05, 0.1), (0.3, 0.2))


def run_law(
    controller: Any, rows: list[list[float]], q: Sequence[float], q_dot: Sequence[float]
) -> list[float]:
    disturbance = 0.02 * np.asarray(q) - 0.01 * np.asarray(q_dot)  # per joint, the same rule for both
    return list(controller.step(np.array(rows), np.array(q), np.array(q_dot), disturbance, DT))


def plant_state(sample: tuple[float, float, float, float]) -> tuple[tuple[float, float], tuple[float, float]]:
    a, b, ad, bd = sample
    return (0.1 * a - 0.05, 0.2 * b + 0.02), (0.3 * ad + 0.1, -0.2 * bd)


@settings(max_examples=40)
@given(data=st.data(), law=st.sampled_from(sorted(LAWS)), history=histories)
def test_law_swap(data: st.DataObject, law: str, history: list[Any]) -> None:
    make, configs, exact = LAWS[law]
    config = data.draw(configs)
    straight, mirrored = make(config, MODEL, False), make(swapped(config), MODEL.swapped(), True)
    same = (lambda x, y: x == y) if exact else agree
    for sample in history:
        rows = reference_rows(sample)
        q, q_dot = plant_state(sample)
        tau = run_law(straight, rows, q, q_dot)
        tau_m = run_law(mirrored, swap_rows(rows), q[::-1], q_dot[::-1])
        assert same(tau_m, tau[::-1])
        assert same(listed(mirrored.internals), flipped(straight.internals))


@settings(max_examples=40)
@given(data=st.data(), law=st.sampled_from(sorted(LAWS)), history=histories, joint=joints, shift=shifts)
def test_law_joint_ignores_the_other_history(
    data: st.DataObject, law: str, history: list[Any], joint: int, shift: float
) -> None:
    make, configs, exact = LAWS[law]
    config = data.draw(configs)
    first, second = make(config, MODEL, False), make(config, MODEL, False)
    same = (lambda x, y: x == y) if exact else agree
    for sample, moved in zip(history, changed(history, 1 - joint, shift), strict=True):
        q, q_dot = plant_state(sample)
        q2, q_dot2 = plant_state(moved)
        tau = run_law(first, reference_rows(sample), q, q_dot)
        tau2 = run_law(second, reference_rows(moved), q2, q_dot2)
        assert same(tau2[joint], tau[joint])
        assert same(joint_of(second.internals, joint), joint_of(first.internals, joint))


@settings(max_examples=40)
@given(config=fpdeso_configs, history=histories, joint=joints, shift=shifts)
def test_fpdeso_pd_terms_ignore_the_other_joint_with_the_real_model(
    config: FPDESOConfig, history: list[Any], joint: int, shift: float
) -> None:
    """kp, kd and u (eq. 11-12) are per joint also with the coupled SMM model."""
    first, second = FPDESOController(config, PARAMS), FPDESOController(config, PARAMS)
    for sample, moved in zip(history, changed(history, 1 - joint, shift), strict=True):
        run_law(first, reference_rows(sample), *plant_state(sample))
        run_law(second, reference_rows(moved), *plant_state(moved))
        keys = ("kp", "kd", "u")
        assert agree(
            {k: v for k, v in joint_of(second.internals, joint).items() if k in keys},
            {k: v for k, v in joint_of(first.internals, joint).items() if k in keys},
        )


# FLESO --------------------------------------------------------------------------------------------------

fleso_configs = st.builds(
    FLESOConfig,
    w0=positive(5.0, 40.0),
    k_w=positive(0.0, 20.0),
    k_s1=positive(0.0, 10.0),
    k_s2=positive(0.0, 2.0),
    w_min=positive(1.0, 30.0),
    grid_points=st.sampled_from([51, 201]),
)


def observer(config: FLESOConfig, model: DecoupledModel) -> FLESO:
    fleso = FLESO(config, PARAMS)
    fleso.model = model  # type: ignore[assignment]
    return fleso


def measurement(sample: tuple[float, float, float, float]) -> tuple[list[float], list[float]]:
    a, b, ad, bd = sample
    return [0.05 * a, 0.05 * b], [ad, bd]


@settings(max_examples=60)
@given(config=fleso_configs, model=decoupled_models, history=histories)
def test_fleso_swap(config: FLESOConfig, model: DecoupledModel, history: list[Any]) -> None:
    straight, mirrored = observer(config, model), observer(swapped(config), model.swapped())
    for sample in history:
        y, tau = measurement(sample)
        xi = straight.step(y, tau, DT)
        xi_m = mirrored.step(y[::-1], tau[::-1], DT)
        assert agree(list(xi_m), list(xi[::-1]))
        assert agree(listed(mirrored.internals), flipped(straight.internals))


@settings(max_examples=60)
@given(config=fleso_configs, model=decoupled_models, history=histories, joint=joints, shift=shifts)
def test_fleso_joint_ignores_the_other_history(
    config: FLESOConfig, model: DecoupledModel, history: list[Any], joint: int, shift: float
) -> None:
    """Error, its rate, fuzzy input, bandwidth, states and estimate of one joint, whatever the other does."""
    first, second = observer(config, model), observer(config, model)
    for sample, moved in zip(history, changed(history, 1 - joint, 0.1 * shift), strict=True):
        xi = first.step(*measurement(sample), DT)
        xi2 = second.step(*measurement(moved), DT)
        assert agree(xi2[joint], xi[joint])
        assert agree(joint_of(second.internals, joint), joint_of(first.internals, joint))


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
