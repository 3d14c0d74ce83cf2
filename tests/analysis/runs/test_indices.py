"""smm_analysis.runs.indices on hand-built recorded runs (no bag files): indices, step target, JSON, table."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from smm_analysis.reproduction.metrics_json import METRICS_UNITS
from smm_analysis.runs.indices import comparison_table, evaluate, metrics_document, step_target
from smm_analysis.runs.recorded import RecordedRun
from smm_bag.manifest import RunManifest

from smm_dynamics import SMMParameters

S = 1_000_000_000


def make_run(
    desired: list[list[float]],
    position: list[list[float]],
    torque: list[list[float]] | None = None,
    *,
    t_s: list[float] | None = None,
    rates: list[list[float]] | None = None,
    manifest: RunManifest | None = None,
    bag: str = "/bags/run",
    latency_ms: list[float] | None = None,
    incomplete_steps: int = 0,
    source: str = "ground truth",
) -> RecordedRun:
    """A run of N steps: q_d (N, 2), position (N, 2), torque (N, 2), stamps in s, q_d' = q_d'' = ``rates``."""
    n = len(desired)
    stamps = np.array([round(t * S) for t in (t_s if t_s is not None else range(n))], dtype=np.int64)
    reference = np.zeros((n, 3, 2))
    reference[:, 0, :] = desired
    if rates is not None:
        reference[:, 1, :] = rates
        reference[:, 2, :] = rates
    return RecordedRun(
        bag=Path(bag),
        manifest=manifest if manifest is not None else RunManifest(),
        t_ns=stamps,
        reference=reference,
        position=np.asarray(position, dtype=np.float64),
        position_source=source,
        measured_position=np.asarray(position, dtype=np.float64),
        command_torque=np.asarray(torque if torque is not None else [[0.0, 0.0]] * n, dtype=np.float64),
        applied_torque=None,
        disturbance_estimate=None,
        latency_ns=None if latency_ms is None else np.array([round(v * 1e6) for v in latency_ms], np.int64),
        incomplete_steps=incomplete_steps,
    )


# A tracking run (q_d moves, so not a step) of three samples 1 s apart; errors q_d - q by hand:
# alpha (0.1, -0.3, 0.2), beta (0, 0, 0.4).
TRACKING = make_run(
    desired=[[0.1, 0.0], [0.2, 0.1], [0.4, 0.2]],
    position=[[0.0, 0.0], [0.5, 0.1], [0.2, -0.2]],
    torque=[[1.0, -3.0], [2.0, 0.0], [4.0, 1.0]],
)


def test_joint_indices_are_eq_42_to_45_of_q_d_minus_the_position_and_of_the_command() -> None:
    joints = evaluate(TRACKING).joints
    alpha, beta = joints["alpha"], joints["beta"]
    assert alpha.Ma == pytest.approx(0.3)
    assert alpha.Ave == pytest.approx(0.2)
    # RMS: trapezoid of e^2 over 2 s: (0.01 + 0.09) / 2 + (0.09 + 0.04) / 2 = 0.115
    rms_alpha, rms_beta = math.sqrt(0.115 / 2.0), math.sqrt(0.08 / 2.0)
    assert pytest.approx(rms_alpha) == alpha.RMS
    assert beta.Ma == pytest.approx(0.4)
    assert beta.Ave == pytest.approx(0.4 / 3.0)
    assert pytest.approx(rms_beta) == beta.RMS
    # eps_u: trapezoid of tau^2: (1 + 4) / 2 + (4 + 16) / 2 = 12.5; beta (9 + 0) / 2 + (0 + 1) / 2 = 5
    assert alpha.eps_u == pytest.approx(12.5)
    assert beta.eps_u == pytest.approx(5.0)
    assert alpha.du_rms == pytest.approx(math.sqrt((1.0 + 4.0) / 2.0))
    assert beta.du_rms == pytest.approx(math.sqrt((9.0 + 1.0) / 2.0))
    assert evaluate(TRACKING).step is None


def test_end_effector_errors_use_the_given_link_length_and_default_to_smm_parameters() -> None:
    # q_d = (0, 0) and q = (0, b): z = L cos b, so the z error is L (1 - cos b) (mm), whatever theta is.
    b = 0.3
    run = make_run([[0.0, 0.0], [0.0, 0.0]], [[0.0, b], [0.0, b]], rates=[[1.0, 0.0], [1.0, 0.0]])
    default = evaluate(run).end_effector
    length = SMMParameters().link_length
    assert default["z"].max_mm == pytest.approx(1000.0 * length * (1.0 - math.cos(b)))
    longer = evaluate(run, SMMParameters(link_length=3.0 * length)).end_effector
    for axis in ("x", "y", "z"):
        assert longer[axis].max_mm == pytest.approx(3.0 * default[axis].max_mm)
        assert longer[axis].rms_mm == pytest.approx(3.0 * default[axis].rms_mm)
    assert longer["z"].rms_mm == pytest.approx(3000.0 * length * (1.0 - math.cos(b)))


def test_a_constant_reference_away_from_the_start_with_zero_derivatives_is_a_step() -> None:
    run = make_run([[1.0, -0.5]] * 3, [[0.2, 0.3], [0.5, 0.0], [0.9, -0.4]])
    target = step_target(run)
    assert target == (1.0, -0.5)
    assert all(type(value) is float for value in target or ())


def test_a_step_on_one_joint_only_is_a_step() -> None:
    assert step_target(make_run([[1.0, 0.3]] * 3, [[0.2, 0.3]] * 3)) == (1.0, 0.3)
    assert step_target(make_run([[0.2, 1.0]] * 3, [[0.2, 0.3]] * 3)) == (0.2, 1.0)


@pytest.mark.parametrize(
    ("desired", "rates", "why"),
    [
        ([[0.2, 0.3]] * 3, None, "a hold at the start position"),
        ([[1.0, 0.5], [1.0, 0.5], [1.0, 0.6]], None, "q_d of beta changes at the last sample"),
        ([[1.0, 0.5], [1.1, 0.5], [1.1, 0.5]], None, "q_d of alpha changes"),
        ([[1.0, 0.5]] * 3, [[0.0, 0.0], [0.0, 0.0], [0.0, 0.1]], "a derivative of beta is not 0"),
        ([[1.0, 0.5]] * 3, [[0.2, 0.0], [0.0, 0.0], [0.0, 0.0]], "a derivative of alpha is not 0"),
    ],
)
def test_other_references_are_not_steps(
    desired: list[list[float]], rates: list[list[float]] | None, why: str
) -> None:
    assert step_target(make_run(desired, [[0.2, 0.3]] * 3, rates=rates)) is None, why


@pytest.mark.parametrize("derivative", [1, 2])
def test_only_one_derivative_not_0_is_not_a_step(derivative: int) -> None:
    run = make_run([[1.0, 0.5]] * 3, [[0.2, 0.3]] * 3)
    run.reference[1, derivative, 0] = 0.5  # q_d' or q_d'' only
    assert step_target(run) is None


def test_a_one_sample_run_has_a_step_target() -> None:
    assert step_target(make_run([[1.0, 0.5]], [[0.2, 0.3]])) == (1.0, 0.5)
    assert step_target(make_run([[0.2, 0.3]], [[0.2, 0.3]])) is None


def test_a_hold_is_judged_on_the_first_position_only() -> None:
    # q_d = the start position, then the joints drift: a hold, not a step
    assert step_target(make_run([[0.2, 0.3]] * 3, [[0.2, 0.3], [0.25, 0.35], [0.3, 0.4]])) is None


# A step of alpha from 0.2 to 1.2 rad reached linearly in 5 s (then held), beta held: t = 0..10 s.
RAMP_T = [0.5 * k for k in range(21)]
RAMP = make_run(
    [[1.2, 0.3]] * 21,
    [[0.2 + min(t / 5.0, 1.0), 0.3] for t in RAMP_T],
    t_s=RAMP_T,
)


def test_step_metrics_are_per_moving_joint_from_the_recorded_start() -> None:
    step = evaluate(RAMP).step
    assert step is not None and set(step) == {"alpha"}
    alpha = step["alpha"]
    # 10 % to 90 % of the 1 rad move: 0.5 s to 4.5 s on the linear ramp (start 0.2, not 0).
    assert alpha.rise_time == pytest.approx(4.0)
    assert alpha.overshoot == pytest.approx(0.0, abs=1e-12)
    # within 2 % of the move from 0.98 of it on: 4.9 s (interpolated between the samples at 4.5 and 5 s)
    assert alpha.settling_time == pytest.approx(4.9)


def test_a_joint_whose_target_is_its_start_gets_no_step_metrics_even_if_it_drifts() -> None:
    drifting = make_run(
        [[1.2, 0.3]] * 21, [[0.2 + min(t / 5.0, 1.0), 0.3 + 0.01 * t] for t in RAMP_T], t_s=RAMP_T
    )
    step = evaluate(drifting).step
    assert step is not None and set(step) == {"alpha"}


def test_both_joints_get_step_metrics_when_both_move() -> None:
    run = make_run(
        [[1.2, -0.7]] * 21, [[0.2 + min(t / 5.0, 1.0), 0.3 - min(t / 5.0, 1.0)] for t in RAMP_T], t_s=RAMP_T
    )
    step = evaluate(run).step
    assert step is not None and set(step) == {"alpha", "beta"}
    assert step["beta"].rise_time == pytest.approx(4.0)


def test_metrics_document_names_runs_by_manifest_and_keeps_every_bag() -> None:
    manifest = RunManifest(version="v1.2", scenario="case2", seed=7, plant="sim", controller="fpdeso")
    first = make_run(
        TRACKING.desired_position.tolist(),
        TRACKING.position.tolist(),
        TRACKING.command_torque.tolist(),
        t_s=[2.0, 3.0, 4.0],
        manifest=manifest,
        bag="/bags/a",
        latency_ms=[1.0, 2.0, 3.0, 4.0, 5.0],
        incomplete_steps=2,
    )
    second = make_run(
        TRACKING.desired_position.tolist(), TRACKING.position.tolist(), manifest=manifest, bag="/bags/b"
    )
    anonymous = make_run(TRACKING.desired_position.tolist(), TRACKING.position.tolist(), bag="/bags/bench7")
    document = metrics_document([evaluate(first), evaluate(second), evaluate(anonymous)])
    assert set(document) == {"case2", "recorded", "meta"}
    case2 = document["case2"]
    assert isinstance(case2, dict)
    assert set(case2) == {"fpdeso", "fpdeso@b"}
    assert case2["fpdeso"]["alpha"]["Ma"] == pytest.approx(0.3)
    assert case2["fpdeso"]["alpha"]["eps_u"] == pytest.approx(12.5)
    assert case2["fpdeso@b"]["alpha"]["eps_u"] == 0.0
    assert set(case2["fpdeso"]) == {"alpha", "beta", "end_effector"}
    recorded = document["recorded"]
    assert isinstance(recorded, dict)
    assert set(recorded) == {"bench7"}
    meta = document["meta"]
    assert isinstance(meta, dict)
    assert meta["source"] == "smm-bag analyze"
    assert meta["units"] == {
        **METRICS_UNITS,
        "latency_ms": "ms, receive time of the command minus receive time of its measurement",
    }
    bags = meta["bags"]
    assert set(bags) == {str(Path("/bags/a")), str(Path("/bags/b")), str(Path("/bags/bench7"))}
    assert bags["/bags/a"] == {
        "scenario": "case2",
        "controller": "fpdeso",
        "position_source": "ground truth",
        "steps": 3,
        "incomplete_steps": 2,
        "late_messages": {},
        "ahead_messages": {},
        "window": "",
        "duration_s": 2.0,
        "seed": 7,
        "plant": "sim",
        "version": "v1.2",
        # median 3 ms; p99 by linear interpolation at rank 0.99 * 4 = 3.96: 4 + 0.96 * (5 - 4) ms; max 5 ms
        "latency_ms": {"median": 3.0, "p99": pytest.approx(4.96, rel=1e-12), "max": 5.0},
    }
    assert bags["/bags/b"]["controller"] == "fpdeso@b"
    assert bags["/bags/b"]["latency_ms"] is None
    assert bags["/bags/bench7"]["scenario"] == "recorded"
    assert bags["/bags/bench7"]["controller"] == "bench7"
    assert bags["/bags/bench7"]["seed"] is None


def test_a_step_run_in_the_document_has_its_step_metrics() -> None:
    document = metrics_document([evaluate(RAMP)])
    entry = document["recorded"]["run"]  # type: ignore[index]
    assert entry["alpha"]["rise_time"] == pytest.approx(4.0)
    assert "rise_time" not in entry["beta"]


def test_comparison_table_side_by_side() -> None:
    never = make_run([[1.2, 0.3]] * 3, [[0.2, 0.3], [0.2, 0.3], [0.2, 0.3]], bag="/bags/stuck")
    tracking = make_run(
        TRACKING.desired_position.tolist(),
        TRACKING.position.tolist(),
        TRACKING.command_torque.tolist(),
        manifest=RunManifest(controller="pid"),
        source="measured",
    )
    lines = comparison_table([evaluate(never), evaluate(tracking)]).splitlines()
    assert lines[0] == "| index | stuck (ground truth) | pid (measured) |"
    assert lines[1] == "|---|---|---|"
    rows = {line.split(" | ")[0][2:]: line.split(" | ")[1:] for line in lines[2:]}
    assert rows["alpha Ma (rad)"] == ["1", "0.3 |"]
    assert rows["alpha Ave (rad)"] == ["1", "0.2 |"]
    assert rows["alpha RMS (rad)"] == ["1", f"{math.sqrt(0.0575):.4g} |"]
    assert rows["alpha eps_u (N^2 m^2 s)"] == ["0", "12.5 |"]
    assert rows["alpha du_rms (N m)"] == ["0", f"{math.sqrt(2.5):.4g} |"]
    assert rows["beta Ma (rad)"] == ["0", "0.4 |"]
    # The stuck run never rises: rise and settling times are inf, shown as "not reached"; the overshoot
    # fraction is 0. The tracking run has no step: "-".
    assert rows["alpha rise_time (s)"] == ["not reached", "- |"]
    assert rows["alpha overshoot_fraction (-)"] == ["0", "- |"]
    assert rows["alpha settling_time (s)"] == ["not reached", "- |"]
    assert "beta rise_time (s)" not in rows  # no run has a beta step
    assert rows["end effector z max (mm)"][1] == f"{evaluate(tracking).end_effector['z'].max_mm:.4g} |"
    assert rows["end effector x RMS (mm)"][1] == f"{evaluate(tracking).end_effector['x'].rms_mm:.4g} |"
    assert rows["end effector z max (mm)"][0] == "0"  # z = L cos(beta), and beta is on target
    assert lines[-1] == "| steps | 3 | 3 |"
    assert len(lines) == 2 + 10 + 3 + 6 + 1


def test_comparison_table_shows_nan_as_a_dash() -> None:
    table = comparison_table([evaluate(make_run([[0.1, 0.0], [0.2, 0.0]], [[0.0, 0.0]] * 2))])
    assert "| alpha Ma (rad) | 0.2 |" in table
    from smm_analysis.runs import indices as analysis

    assert analysis._number(math.nan) == "-"
    assert analysis._number(None) == "-"
    assert analysis._number(-math.inf) == "not reached"
    assert analysis._number(123456.0) == "1.235e+05"
