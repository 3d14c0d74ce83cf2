"""The excitation reference: a Fourier series at rest at both ends, inside every limit it is given."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from smm_controller.excitation import ExcitationReference
from smm_controller.reference import REFERENCE_KINDS, make_reference

from smm_dynamics import SMMParameters, inverse_dynamics

DEFAULT = ExcitationReference()


def _run(reference: ExcitationReference, points: int = 40001) -> tuple[np.ndarray, np.ndarray]:
    times = np.linspace(0.0, reference.duration + 1.0, points)
    return times, reference.sample(times)


def test_is_a_reference_kind() -> None:
    assert REFERENCE_KINDS["excite"] is ExcitationReference
    assert make_reference("excite", start=[0.1, -0.1]).start == (0.1, -0.1)


@pytest.mark.parametrize(
    "reference", [DEFAULT, ExcitationReference(start=(0.2, -0.3), periods=1, harmonics=4)]
)
def test_starts_and_ends_at_rest_at_the_start_position(reference: ExcitationReference) -> None:
    for t in (0.0, reference.start_time, reference.duration, reference.duration + 3.0):
        rows = reference.evaluate(t)
        assert_allclose(rows[0], reference.start, atol=1e-12)
        assert_allclose(rows[1:], 0.0, atol=1e-12)
    # Continuous at both ends: just inside, velocity and acceleration are still near zero.
    for t in (reference.start_time + 1e-6, reference.duration - 1e-6):
        rows = reference.evaluate(t)
        assert np.all(np.abs(rows[1]) < 1e-4) and np.all(
            np.abs(rows[2]) < 1e-3 * max(reference.acceleration_limit)
        )


def test_velocity_and_acceleration_are_the_derivatives() -> None:
    times, sampled = _run(DEFAULT)
    step = times[1] - times[0]
    inside = (times > DEFAULT.start_time + 0.01) & (times < DEFAULT.duration - 0.01)
    for row in (0, 1):
        derivative = np.gradient(sampled[:, row, :], step, axis=0)
        scale = np.abs(sampled[:, row + 1, :]).max()
        assert_allclose(derivative[inside], sampled[inside, row + 1, :], atol=1e-4 * scale)


@pytest.mark.parametrize(
    "reference",
    [
        DEFAULT,
        ExcitationReference(velocity_limit=(0.5, 3.0)),
        ExcitationReference(acceleration_limit=(2.0, 20.0), velocity_limit=(5.0, 5.0)),
        ExcitationReference(position_limit=(0.3, 0.2), start=(0.1, 0.0)),
        ExcitationReference(torque_limit=(0.6, 0.7)),
    ],
)
def test_stays_within_every_limit_and_reaches_one(reference: ExcitationReference) -> None:
    _, sampled = _run(reference)
    position, velocity, acceleration = sampled[:, 0, :], sampled[:, 1, :], sampled[:, 2, :]
    torque = inverse_dynamics(position, velocity, acceleration, SMMParameters())
    ratios = np.concatenate(
        [
            np.abs(position).max(axis=0) / reference.position_limit,
            np.abs(velocity).max(axis=0) / reference.velocity_limit,
            np.abs(acceleration).max(axis=0) / reference.acceleration_limit,
            np.abs(torque).max(axis=0) / reference.torque_limit,
        ]
    )
    assert ratios.max() <= 1.0
    assert ratios.max() > 0.99  # the design uses the room it is given (0.1 % margin)


def test_the_torque_limit_binds_when_tight() -> None:
    loose = ExcitationReference()
    tight = ExcitationReference(torque_limit=(0.6, 0.7))
    assert tight.scale < loose.scale


def test_crest_factor_is_low_and_reported_per_joint() -> None:
    crest = DEFAULT.crest_factor()
    assert len(crest) == 2
    # A single sine has sqrt(2); a multisine with Schroeder phases stays near it, random phases go far above.
    assert all(np.sqrt(2.0) <= value < 2.2 for value in crest)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"period": 0.0}, r"^period must be > 0"),
        ({"harmonics": 2}, r"^harmonics must be >= 3"),
        ({"harmonics": 4.0}, r"^harmonics must be an integer"),
        ({"periods": 0}, r"^periods must be >= 1"),
        ({"velocity_limit": (1.0, -1.0)}, r"^velocity_limit must be > 0"),
        ({"start": (1.2, 0.0)}, r"^start .* inside \+-position_limit"),
        ({"torque_limit": (0.1, 0.1), "start": (0.0, 0.7)}, r"^torque_limit .* below the nominal torque"),
    ],
)
def test_invalid_designs_name_the_field(overrides: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ExcitationReference(**overrides)  # type: ignore[arg-type]
