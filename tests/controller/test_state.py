"""reset() restores the initial behaviour; internals are read-only copies (every algorithm)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose
from smm_controller.baselines import FPDController, NPDController, PIDController
from smm_controller.chain import ControlChain, make_chain
from smm_controller.fleso import FLESO
from smm_controller.fpdeso import FPDESOController
from smm_controller.fuzzy_pd import FuzzyPDGainSchedule
from smm_controller.reference import SineReference
from smm_controller.td import TrackingDifferentiator

from smm_dynamics import SMMParameters

DT = 0.001
PARAMS = SMMParameters()
REFERENCES = SineReference().sample(np.arange(60) * DT)


def measurements(k: int) -> np.ndarray:
    return np.array([0.8 * np.sin(3.0 * k * DT) + 0.01 * np.cos(40.0 * k * DT), 0.3 * np.sin(2.0 * k * DT)])


def run_td(algorithm: TrackingDifferentiator, k: int) -> np.ndarray:
    return np.concatenate(algorithm.step(measurements(k), DT))


def run_fleso(algorithm: FLESO, k: int) -> np.ndarray:
    return algorithm.step(measurements(k), [0.2 * np.sin(k * DT), -0.1], DT)


def run_schedule(algorithm: FuzzyPDGainSchedule, k: int) -> np.ndarray:
    return np.concatenate(algorithm.step(REFERENCES[k, 0] - measurements(k), REFERENCES[k, 1]))


def run_controller(algorithm: Any, k: int) -> np.ndarray:
    return algorithm.step(REFERENCES[k], measurements(k), [0.1, -0.2], [0.05, -0.02], DT)  # type: ignore[no-any-return]


def run_chain(algorithm: ControlChain, k: int) -> np.ndarray:
    return algorithm.step(measurements(k), [0.3, -0.1], REFERENCES[k], DT)


CASES: list[tuple[str, Callable[[], Any], Callable[[Any, int], np.ndarray]]] = [
    ("td", TrackingDifferentiator, run_td),
    ("fleso", lambda: FLESO(None, PARAMS), run_fleso),
    ("schedule", FuzzyPDGainSchedule, run_schedule),
    ("fpdeso", lambda: FPDESOController(None, PARAMS), run_controller),
    ("pid", PIDController, run_controller),
    ("npd", NPDController, run_controller),
    ("fpd", FPDController, run_controller),
    ("chain-fpdeso", lambda: make_chain("fpdeso", PARAMS), run_chain),
    ("chain-pid", lambda: make_chain("pid", PARAMS), run_chain),
]


@pytest.mark.parametrize(("name", "factory", "run"), CASES, ids=[c[0] for c in CASES])
def test_reset_restores_initial_behaviour(
    name: str, factory: Callable[[], Any], run: Callable[[Any, int], np.ndarray]
) -> None:
    algorithm = factory()
    first = np.array([run(algorithm, k) for k in range(60)])
    first_internals = {key: value.copy() for key, value in algorithm.internals.items()}
    algorithm.reset()
    second = np.array([run(algorithm, k) for k in range(60)])
    assert_allclose(second, first, rtol=0, atol=0)
    for key, value in algorithm.internals.items():
        assert_allclose(value, first_internals[key], rtol=0, atol=0)
    # A fresh object agrees too, so reset really restores construction state.
    fresh = factory()
    assert_allclose(np.array([run(fresh, k) for k in range(60)]), first, rtol=0, atol=0)


@pytest.mark.parametrize(("name", "factory", "run"), CASES, ids=[c[0] for c in CASES])
def test_internals_are_read_only_copies(
    name: str, factory: Callable[[], Any], run: Callable[[Any, int], np.ndarray]
) -> None:
    algorithm = factory()
    run(algorithm, 0)
    run(algorithm, 1)
    internals = algorithm.internals
    assert internals, "every algorithm exposes internals"
    snapshot = {key: value.copy() for key, value in internals.items()}
    for key, value in internals.items():
        assert value.shape == (2,), key
        with pytest.raises(ValueError, match="read-only"):
            value[0] = 123.0
    with pytest.raises(TypeError):
        internals["new"] = np.zeros(2)
    for k in range(2, 10):
        run(algorithm, k)
    for key, value in internals.items():
        assert_allclose(value, snapshot[key], rtol=0, atol=0)


@pytest.mark.parametrize(("name", "factory", "run"), CASES, ids=[c[0] for c in CASES])
def test_internals_are_zero_before_the_first_step_and_after_reset(
    name: str, factory: Callable[[], Any], run: Callable[[Any, int], np.ndarray]
) -> None:
    algorithm = factory()
    for _ in range(2):
        for key, value in algorithm.internals.items():
            assert value.shape == (2,), key
            assert list(value) == [0.0, 0.0], key
        for k in range(3):
            run(algorithm, k)
        algorithm.reset()


# (algorithm, call with one argument of the wrong shape, the argument's name)
SHAPE_CASES: list[tuple[str, Callable[[], Any]]] = [
    ("v", lambda: TrackingDifferentiator().step([0.0], DT)),
    ("y", lambda: FLESO(None, PARAMS).step([0.0], [0.0, 0.0], DT)),
    ("tau_applied", lambda: FLESO(None, PARAMS).step([0.0, 0.0], [0.0, 0.0, 0.0], DT)),
    ("e", lambda: FuzzyPDGainSchedule().step([0.0], [0.0, 0.0])),
    ("e_dot", lambda: FuzzyPDGainSchedule().step([0.0, 0.0], [0.0])),
    ("q", lambda: PIDController().step(REFERENCES[0], [0.0], [0.0, 0.0], [0.0, 0.0], DT)),
    ("q_dot", lambda: NPDController().step(REFERENCES[0], [0.0, 0.0], [0.0], [0.0, 0.0], DT)),
    ("disturbance_estimate", lambda: FPDController().step(REFERENCES[0], [0.0, 0.0], [0.0, 0.0], [0.0], DT)),
]


@pytest.mark.parametrize(("name", "call"), SHAPE_CASES, ids=[c[0] for c in SHAPE_CASES])
def test_shape_errors_name_the_argument(name: str, call: Callable[[], Any]) -> None:
    with pytest.raises(ValueError, match=rf"^{name} must have shape \(2,\)"):
        call()
