"""How well a reference excites the model: the regressor's condition number over it and its crest factor."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from smm_controller.excitation import ExcitationReference

from smm_analysis.identification.regressor import regressor
from smm_dynamics import SMMParameters

__all__ = ["ExcitationQuality", "excitation_quality"]


@dataclass(frozen=True)
class ExcitationQuality:
    """The excitation's figures of merit.

    Attributes:
        condition_number: Of the column-scaled regressor Y(q_d, q_d', q_d'') over the excitation (both
            joints' rows stacked); 1 is ideal, large means some parameters are barely separated.
        crest_factor: Peak over RMS of each joint's q_d' (dimensionless; a sine has sqrt(2)).
    """

    condition_number: float
    crest_factor: tuple[float, float]


def excitation_quality(
    reference: ExcitationReference, params: SMMParameters | None = None, *, samples: int = 4000
) -> ExcitationQuality:
    """The condition number of the regressor along ``reference`` and its crest factor."""
    params = params if params is not None else SMMParameters()
    times = np.linspace(reference.start_time, reference.duration, samples)
    rows = reference.sample(times)
    y = regressor(
        rows[:, 0], rows[:, 1], rows[:, 2], gravity=params.gravity, gravity_sign=params.gravity_sign
    )
    matrix = y.reshape(-1, y.shape[-1])
    matrix = matrix / np.sqrt(np.sum(matrix**2, axis=0))
    singular = np.linalg.svd(matrix, compute_uv=False)
    return ExcitationQuality(float(singular[0] / singular[-1]), reference.crest_factor())
