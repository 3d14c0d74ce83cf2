"""Bounded least squares of the SMM's parameters, with identifiability, bootstrap intervals and fit.

Method (``scipy.optimize.lsq_linear``, block bootstrap): docs/IDENTIFICATION.md, "How it estimates".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import lsq_linear

from smm_analysis.errors import NotExcitingError, NotPhysicalError
from smm_analysis.identification.data import PreparedRun
from smm_analysis.identification.regressor import (
    PARAMETER_NAMES,
    parameter_vector,
    parameters_from_vector,
)
from smm_analysis.identification.sums import RunSums, sums_of
from smm_dynamics import SMMParameters, mass_matrix

__all__ = ["EstimationSettings", "Identification", "RunFit", "estimate", "fit_of", "identify"]

FloatArray = NDArray[np.float64]
_LOWER = np.array([1e-9] * 4 + [0.0] * 5 + [-np.inf] * 2)


@dataclass(frozen=True)
class EstimationSettings:
    """Settings of the estimate (reported with it).

    Attributes:
        bootstrap: Bootstrap replicates, integer >= 20.
        block: Length of a bootstrap block (s), > 0.
        seed: Seed of the bootstrap's generator, >= 0.
        rank_tolerance: A singular value of the column-scaled regressor below this times the largest counts
            as zero (rank deficient), in (0, 1).
        workspace: M(q) is checked positive definite on |alpha|, |beta| <= workspace (rad), each in (0, pi/2).
    """

    bootstrap: int = 200
    block: float = 1.0
    seed: int = 0
    rank_tolerance: float = 1e-4
    workspace: tuple[float, float] = (1.3, 1.3)

    def __post_init__(self) -> None:
        if isinstance(self.bootstrap, bool) or not isinstance(self.bootstrap, int) or self.bootstrap < 20:
            raise ValueError(f"bootstrap must be an integer >= 20, got {self.bootstrap!r}")
        if not (math.isfinite(self.block) and self.block > 0.0):
            raise ValueError(f"block must be a finite number > 0 s, got {self.block!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {self.seed!r}")
        if not 0.0 < self.rank_tolerance < 1.0:
            raise ValueError(f"rank_tolerance must be in (0, 1), got {self.rank_tolerance!r}")
        if len(self.workspace) != 2 or not all(0.0 < value < 0.5 * math.pi for value in self.workspace):
            raise ValueError(f"workspace must be 2 values in (0, pi/2) rad, got {self.workspace!r}")


@dataclass(frozen=True)
class RunFit:
    """How well a model predicts one run's torque.

    Attributes:
        name: The run.
        nrmse: RMS(measured - predicted) / RMS(measured) per joint over the used rows.
    """

    name: str
    nrmse: tuple[float, float]


@dataclass(frozen=True)
class Identification:
    """An estimate and what it rests on.

    Attributes:
        params: The identified SMMParameters (gravity, its sign and L from the base).
        theta: Estimates in :data:`PARAMETER_NAMES` order, shape (11,).
        standard_error: Bootstrap standard deviations, shape (11,).
        interval: 95 % percentile intervals, shape (11, 2).
        at_bound: Names of the parameters the bounds hold at their limit.
        rank: Rank of the column-scaled regressor.
        condition_number: Its condition number (largest over smallest singular value).
        singular_values: Its singular values, largest first.
        min_mass_eigenvalue: Smallest eigenvalue of M(q) over the workspace grid (kg m^2).
        fits: Fit on each identification run.
        rows: Joint rows used.
        settings: The estimation settings.
        largest_torque: Largest |applied torque| over the used rows (N m).
        bootstrap_condition: Largest condition number of the column-scaled regressor over the replicates.
    """

    params: SMMParameters
    theta: FloatArray
    standard_error: FloatArray
    interval: FloatArray
    at_bound: tuple[str, ...]
    rank: int
    condition_number: float
    singular_values: FloatArray
    min_mass_eigenvalue: float
    fits: tuple[RunFit, ...]
    rows: int
    settings: EstimationSettings
    largest_torque: float
    bootstrap_condition: float


def _solve_normal(gram: FloatArray, moment: FloatArray, scale: FloatArray) -> FloatArray:
    """Bounded least squares from A^T A and A^T b: lsq_linear on the Cholesky factor (same minimiser)."""
    scaled_gram = gram / np.outer(scale, scale)
    factor = np.linalg.cholesky(scaled_gram).T  # R with R^T R = A_s^T A_s
    target = np.linalg.solve(factor.T, moment / scale)
    result = lsq_linear(factor, target, bounds=(_LOWER * scale, np.inf), method="bvls")
    solution: FloatArray = result.x / scale
    return solution


def _weights(
    gram: FloatArray, moment: FloatArray, square: FloatArray, count: FloatArray, theta: FloatArray
) -> FloatArray:
    """1 / RMS of each joint's residual (1 for a joint without rows), from its sums, shape (2,)."""
    weights = np.ones(2)
    for joint in (0, 1):
        if count[joint] > 0:
            residual = square[joint] - 2.0 * theta @ moment[joint] + theta @ gram[joint] @ theta
            weights[joint] = 1.0 / max(math.sqrt(max(float(residual), 0.0) / count[joint]), 1e-12)
    return weights


def _inseparable(scaled_gram: FloatArray, tolerance: float) -> tuple[int, FloatArray, list[str]]:
    """Rank, singular values (largest first) and inseparable parameters of A_s, from A_s^T A_s."""
    eigenvalues, vectors = np.linalg.eigh(scaled_gram)
    order = np.argsort(eigenvalues)[::-1]
    singular: FloatArray = np.sqrt(np.clip(eigenvalues[order], 0.0, None))
    rank = int(np.sum(singular > tolerance * singular[0]))
    if rank == scaled_gram.shape[1]:
        return rank, singular, []
    null = vectors[:, order[rank:]].T
    involved = np.sqrt(np.sum(null**2, axis=0)) > 0.1
    return rank, singular, [name for name, flag in zip(PARAMETER_NAMES, involved, strict=True) if flag]


def _min_mass_eigenvalue(params: SMMParameters, workspace: tuple[float, float]) -> float:
    alpha = np.linspace(-workspace[0], workspace[0], 61)
    beta = np.linspace(-workspace[1], workspace[1], 61)
    grid = np.stack(np.meshgrid(alpha, beta, indexing="ij"), axis=-1).reshape(-1, 2)
    return float(np.linalg.eigvalsh(mass_matrix(grid, params)).min())


def fit_of(run: PreparedRun, params: SMMParameters) -> RunFit:
    """The NRMSE per joint of the torque ``params`` predict on ``run``, over the used rows."""
    return RunFit(run.name, sums_of(run, EstimationSettings.block).nrmse(parameter_vector(params)))


def identify(
    runs: Sequence[PreparedRun], base: SMMParameters | None = None, settings: EstimationSettings | None = None
) -> Identification:
    """Estimates the 11 parameters from runs prepared in memory (see :func:`estimate`)."""
    settings = settings if settings is not None else EstimationSettings()
    return estimate([sums_of(run, settings.block) for run in runs], base, settings)


def estimate(
    runs: Sequence[RunSums], base: SMMParameters | None = None, settings: EstimationSettings | None = None
) -> Identification:
    """Estimates the 11 parameters from the sums of runs.

    Args:
        runs: The sums of the identification runs (at least one), their blocks of ``settings.block`` s.
        base: Supplies gravity, its sign and L (default ``SMMParameters()``); its other values are not used.
        settings: Estimation settings (default :class:`EstimationSettings`).

    Returns:
        The estimate with intervals, identifiability and fit.

    Raises:
        NotExcitingError: The regressor is rank deficient; names the parameters the data cannot separate.
        NotPhysicalError: M(q) of the estimate is not positive definite over the workspace.
    """
    if not runs:
        raise ValueError("estimate needs at least one run")
    base = base if base is not None else SMMParameters()
    settings = settings if settings is not None else EstimationSettings()
    totals = [run.totals() for run in runs]
    gram, moment, square, count = (np.sum([total[part] for total in totals], axis=0) for part in range(4))
    scale = np.sqrt(np.diag(gram.sum(axis=0)))
    dead = [name for name, value in zip(PARAMETER_NAMES, scale, strict=True) if value == 0.0]
    if dead:
        raise NotExcitingError(
            f"the data do not excite {', '.join(dead)} at all (rank < {len(PARAMETER_NAMES)}): "
            "record a run in which every joint moves both ways (the excite scenario)"
        )
    first = _solve_normal(gram.sum(axis=0), moment.sum(axis=0), scale)
    squared = _weights(gram, moment, square, count, first) ** 2
    weighted, target = np.tensordot(squared, gram, axes=1), np.tensordot(squared, moment, axes=1)
    scale = np.sqrt(np.diag(weighted))
    rank, singular, inseparable = _inseparable(weighted / np.outer(scale, scale), settings.rank_tolerance)
    if inseparable:
        raise NotExcitingError(
            f"the data cannot separate {', '.join(inseparable)} (rank {rank} of {len(PARAMETER_NAMES)}, "
            f"condition number {singular[0] / singular[-1]:.3g}): record a richer excitation "
            "(the excite scenario) instead of inventing values for them"
        )
    theta = _solve_normal(weighted, target, scale)
    params = parameters_from_vector(theta, base)
    min_eigenvalue = _min_mass_eigenvalue(params, settings.workspace)
    if not min_eigenvalue > 0.0:
        raise NotPhysicalError(
            f"M(q) of the estimate is not positive definite on |q| <= {settings.workspace} rad "
            f"(smallest eigenvalue {min_eigenvalue:.3g} kg m^2): the data do not pin the inertias down"
        )
    grams = np.tensordot(np.concatenate([run.grams for run in runs]), squared, axes=([1], [0]))
    moments = np.tensordot(np.concatenate([run.moments for run in runs]), squared, axes=([1], [0]))
    replicates, bootstrap_condition = _bootstrap(grams, moments, scale, settings)
    at_bound = tuple(
        name
        for name, value, low in zip(PARAMETER_NAMES, theta, _LOWER, strict=True)
        if value <= low * (1 + 1e-9) + 1e-15
    )
    return Identification(
        params=params,
        theta=theta,
        standard_error=replicates.std(axis=0, ddof=1),
        interval=np.percentile(replicates, [2.5, 97.5], axis=0).T,
        at_bound=at_bound,
        rank=rank,
        condition_number=float(singular[0] / singular[-1]),
        singular_values=singular,
        min_mass_eigenvalue=min_eigenvalue,
        fits=tuple(RunFit(run.name, run.nrmse(theta)) for run in runs),
        rows=sum(run.rows for run in runs),
        settings=settings,
        largest_torque=max(run.largest for run in runs),
        bootstrap_condition=bootstrap_condition,
    )


def _bootstrap(
    grams: FloatArray, moments: FloatArray, scale: FloatArray, settings: EstimationSettings
) -> tuple[FloatArray, float]:
    """Estimates of ``settings.bootstrap`` replicates, each the blocks drawn with replacement (B, 11).

    Also the largest condition number of a replicate's column-scaled regressor.

    grams: Weighted Y^T Y per block (b, 11, 11); moments: weighted Y^T tau per block (b, 11).
    """
    generator = np.random.default_rng(settings.seed)
    blocks = grams.shape[0]
    replicates = np.empty((settings.bootstrap, grams.shape[1]))
    condition = 0.0
    for index in range(settings.bootstrap):
        counts = np.bincount(generator.integers(0, blocks, blocks), minlength=blocks)
        gram = np.tensordot(counts, grams, axes=1)
        replicates[index] = _solve_normal(gram, np.tensordot(counts, moments, axes=1), scale)
        eigenvalues = np.linalg.eigvalsh(gram / np.outer(scale, scale))
        condition = max(condition, math.sqrt(eigenvalues[-1] / max(eigenvalues[0], 1e-300)))
    return replicates, condition
