"""Every config rejects invalid values with a ValueError naming the field."""

from __future__ import annotations

import math
import re
from typing import Any

import pytest
from smm_controller.baselines import FPDConfig, NPDConfig, PIDConfig
from smm_controller.fleso import FLESOConfig
from smm_controller.fpdeso import FPDESOConfig
from smm_controller.fuzzy_pd import PAPER_FPD_FUZZY, PAPER_FPDESO_FUZZY, FuzzyPDConfig
from smm_controller.reference import RampHoldReference, SineReference, StepReference
from smm_controller.td import TrackingDifferentiatorConfig

NAN = math.nan
INF = math.inf

# (config class, field, bad value): one line per rejection class and field kind.
CASES: list[tuple[type[Any], str, object]] = [
    # fuzzy PD: positive scalings, non-negative output scales, positive base gains
    (FuzzyPDConfig, "k_e", (0.0, 6.0)),
    (FuzzyPDConfig, "k_e", (-2.0, 6.0)),
    (FuzzyPDConfig, "k_e", (NAN, 6.0)),
    (FuzzyPDConfig, "k_e", (INF, 6.0)),
    (FuzzyPDConfig, "k_de", (5.0,)),
    (FuzzyPDConfig, "k_de", (5.0, 2.0, 1.0)),
    (FuzzyPDConfig, "k_de", [5.0, 2.0]),
    (FuzzyPDConfig, "k1", (-1.0, 13.0)),
    (FuzzyPDConfig, "k1", (True, 13.0)),
    (FuzzyPDConfig, "k2", ("0.5", 0.9)),
    (FuzzyPDConfig, "kp0", (0.0, 4150.0)),
    (FuzzyPDConfig, "kd0", (110.0, -90.0)),
    (FuzzyPDConfig, "grid_points", 2),
    (FuzzyPDConfig, "grid_points", 201.0),
    (FuzzyPDConfig, "grid_points", True),
    # FLESO
    (FLESOConfig, "w0", (0.0, 28.0)),
    (FLESOConfig, "w0", (NAN, 28.0)),
    (FLESOConfig, "k_w", (-11.0, 20.0)),
    (FLESOConfig, "k_w", (INF, 20.0)),
    (FLESOConfig, "k_s1", (3.0,)),
    (FLESOConfig, "k_s2", (-1.15, 0.98)),
    (FLESOConfig, "w_min", (0.0, 1.0)),
    (FLESOConfig, "w_min", (-1.0, 1.0)),
    (FLESOConfig, "grid_points", 0),
    # FPDESO
    (FPDESOConfig, "robust_gain", (-0.1, 0.1)),
    (FPDESOConfig, "robust_gain", (NAN, 0.1)),
    (FPDESOConfig, "boundary_layer", (-1.0, 0.0)),
    (FPDESOConfig, "boundary_layer", (INF, 0.0)),
    (FPDESOConfig, "fuzzy", {"k_e": (2.0, 6.0)}),
    # PID: non-negative gains, positive filter, positive (possibly infinite) limits
    (PIDConfig, "kp", (-10.0, 50.0)),
    (PIDConfig, "ki", (NAN, 3.0)),
    (PIDConfig, "kd", (1.5, INF)),
    (PIDConfig, "derivative_filter", (0.0, 1456.0)),
    (PIDConfig, "derivative_filter", (INF, 1456.0)),
    (PIDConfig, "integrator_limit", (0.0, 1.0)),
    (PIDConfig, "integrator_limit", (-INF, 1.0)),
    (PIDConfig, "output_limit", (NAN, 1.0)),
    (PIDConfig, "output_limit", (1.0,)),
    # NPD: everything positive
    (NPDConfig, "k_np", (0.0, 20.0)),
    (NPDConfig, "k_nd", (0.8, -0.5)),
    (NPDConfig, "delta_p", (0.0, 0.1)),
    (NPDConfig, "delta_d", (NAN, 0.2)),
    (NPDConfig, "rho_p", (0.0, 0.6)),
    (NPDConfig, "rho_d", (1.1, INF)),
    # FPD
    (FPDConfig, "fuzzy", None),
    # Sign rules of every remaining field (a dropped positive/non_negative flag is caught).
    (FuzzyPDConfig, "k_de", (-5.0, 2.0)),
    (FuzzyPDConfig, "k2", (0.5, -0.9)),
    (FLESOConfig, "k_s1", (-3.0, 5.0)),
    (FLESOConfig, "k_s2", (1.15, -0.98)),
    (FLESOConfig, "w_min", (1.0, -1.0)),
    (PIDConfig, "kp", (-10.0, 50.0)),
    (PIDConfig, "ki", (-0.9, 3.0)),
    (PIDConfig, "kd", (1.5, -0.5)),
    (PIDConfig, "derivative_filter", (0.0, 1456.0)),
    (PIDConfig, "output_limit", (0.0, 1.0)),
    (PIDConfig, "output_limit", (-1.0, 1.0)),
    (FPDESOConfig, "robust_gain", (-0.1, 0.0)),
    (TrackingDifferentiatorConfig, "speed", (0.0, 1e5)),
    (TrackingDifferentiatorConfig, "filter_factor", (0.001, -0.001)),
    # Reference generators
    (StepReference, "amplitude", (NAN, 0.0)),
    (StepReference, "start_time", -1.0),
    (SineReference, "amplitude", (INF, 0.0)),
    (SineReference, "angular_frequency", 0.0),
    (SineReference, "phase", (0.0, NAN)),
    (RampHoldReference, "target", (NAN, 0.0)),
    (RampHoldReference, "ramp_time", 0.0),
    (RampHoldReference, "start_time", -0.5),
    (RampHoldReference, "initial", (0.0, INF)),
    (RampHoldReference, "profile", "cubic"),
]


@pytest.mark.parametrize(
    ("config", "field", "value"), CASES, ids=[f"{c.__name__}-{f}-{v!r}" for c, f, v in CASES]
)
def test_rejection(config: type[Any], field: str, value: object) -> None:
    with pytest.raises(ValueError, match=rf"^{re.escape(field)} must"):
        config(**{field: value})


@pytest.mark.parametrize(("scale", "base"), [("k1", "kp0"), ("k2", "kd0")])
def test_fuzzy_scale_must_keep_gains_positive(scale: str, base: str) -> None:
    with pytest.raises(ValueError, match=f"{scale} must be < {base}"):
        FuzzyPDConfig(**{scale: (5.0, 5.0), base: (5.0, 6.0)})  # type: ignore[arg-type]


def test_defaults_are_the_paper_gains() -> None:
    assert FuzzyPDConfig() == PAPER_FPDESO_FUZZY
    assert PAPER_FPDESO_FUZZY.kp0 == (4050.0, 4150.0)
    assert PAPER_FPD_FUZZY.k_e == (8.0, 5.0)
    assert FPDConfig().fuzzy == PAPER_FPD_FUZZY
    assert FPDESOConfig().robust_gain == pytest.approx((0.03 * math.pi, 0.02 * math.pi))
    assert FLESOConfig().w0 == (20.0, 28.0)
    assert PIDConfig().derivative_filter == (500.0, 1456.0)
    assert NPDConfig().rho_p == (1.2, 0.6)


def test_infinite_limits_mean_no_limit() -> None:
    config = PIDConfig()
    assert config.integrator_limit == (INF, INF)
    assert config.output_limit == (INF, INF)


def test_configs_are_frozen() -> None:
    config = FLESOConfig()
    with pytest.raises(AttributeError):
        config.w0 = (1.0, 1.0)  # type: ignore[misc]
