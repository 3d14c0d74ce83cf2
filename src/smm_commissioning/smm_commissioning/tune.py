"""``tune``: a gain sweep (``smm-sweep``'s library) on the identified model, plants drawn from its intervals.

The FPDESO gains k_p0 and k_d0 scaled by a grid of factors (the paper's among them); case 1 on the
identified plant with the bench's valve lag, torque limit, D/A quantum and encoder noise, each gain set on
plants drawn uniformly within the 95 % intervals. The chosen set is no worse than the paper's on either
joint in the worst draw and has the least alpha RMS. docs/COMMISSIONING.md, "tune".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from smm_analysis.errors import AnalysisError
from smm_analysis.identification import PARAMETER_NAMES
from smm_analysis.sweep.execute import read_parts, run_sweep
from smm_analysis.sweep.outputs import parameters_sections, write_outputs
from smm_analysis.sweep.results import SweepResult, analyse
from smm_analysis.sweep.spec import SweepSpec, parse_spec
from smm_controller.fpdeso import FPDESOConfig
from smm_hw_bridge.bridge_config import BridgeConfig
from smm_schema.ranges import above, bounds, check_bounds

from smm_commissioning.errors import CommissioningError
from smm_dynamics import SMMParameters

__all__ = ["TuneConfig", "TuneResult", "plant_values", "run_tune", "tune_spec"]

FloatArray = NDArray[np.float64]
_MODEL = ("I11", "I22", "I44", "I55", "mass_lever")
_PER_JOINT = ("viscous_friction", "coulomb_friction", "torque_offset")


@dataclass(frozen=True)
class TuneConfig:
    """The sweep ``tune`` runs.

    Attributes:
        duration: Case 1's length in every run (s), in [1, 30].
        draws: Plants drawn from the identified intervals per gain set, in [1, 1000].
        factors: Factors on the paper's k_p0 and k_d0 (both joints), each > 0, 1.0 among them.
        seed: Seed of the plant draws, >= 0.
        workers: Local processes of the sweep, in [1, 64].
    """

    duration: float = field(default=2.0, metadata=bounds(1.0, 30.0))
    draws: int = field(default=3, metadata=bounds(1, 1000))
    factors: tuple[float, ...] = field(default=(0.8, 1.0, 1.25), metadata=above(0.0))
    seed: int = field(default=0, metadata=bounds(0, 2**31))
    workers: int = field(default=1, metadata=bounds(1, 64))

    def __post_init__(self) -> None:
        check_bounds(self)
        if 1.0 not in self.factors:
            raise ValueError(f"factors must hold 1.0 (the paper's gains), got {self.factors!r}")


@dataclass(frozen=True)
class TuneResult:
    """The sweep and its choice.

    Attributes:
        spec: The sweep (with the constraints of the choice).
        result: Its statistics and choice.
        table: Every run's indices (a pyarrow Table).
        paper: Index of the paper's gain set.
        sections: The chosen set's controller parameters (``chosen.yaml``'s sections).
    """

    spec: SweepSpec
    result: SweepResult
    table: Any
    paper: int
    sections: dict[str, dict[str, Any]]

    @property
    def chosen(self) -> int:
        """Index of the chosen gain set."""
        assert self.result.chosen is not None
        return self.result.chosen

    def worst(self, gain_set: int) -> tuple[float, float]:
        """Worst case-1 RMS of a gain set over the draws (alpha, beta) (rad)."""
        worst = self.result.statistics["worst"]
        columns = self.result.columns
        return (
            float(worst[gain_set, columns.index("case1.RMS_alpha")]),
            float(worst[gain_set, columns.index("case1.RMS_beta")]),
        )


def plant_values(
    params: SMMParameters, bridge: BridgeConfig, noise_std: tuple[float, float]
) -> dict[str, Any]:
    """The sweep's fixed plant (``smm_sim_node``'s names): the identified model on the bench's valves."""
    valve = bridge.valve
    limit, quantum = [], []
    for j in range(2):
        negative = valve.gain_negative[j] or valve.gain[j]
        room = valve.code_limit[j] - abs(valve.null_bias[j]) - valve.deadband[j]  # the link's full scale
        limit.append(min(room / valve.gain[j], room / negative))
        quantum.append(1.0 / max(valve.gain[j], negative))
    values: dict[str, Any] = {f"params.{name}": float(getattr(params, name)) for name in _MODEL}
    for name in _PER_JOINT:
        values[f"params.{name}"] = [float(v) for v in getattr(params, name)]
    values.update(
        {
            "valve_time_constants": [float(t) for t in valve.time_constants],
            "torque_limit": limit,
            "torque_quantum": quantum,
            "noise_std": [float(s) for s in noise_std],
            "encoder_counts_per_rev": int(bridge.encoder.counts_per_rev[0]),
        }
    )
    return values


def _draws(interval: FloatArray) -> dict[str, Any]:
    """Uniform draws within each identified 95 % interval (inertias > 0, lever and friction >= 0)."""
    draws: dict[str, Any] = {}
    for index, name in enumerate(PARAMETER_NAMES):
        base, _, joint = name.partition(".")
        low, high = (float(v) for v in interval[index])
        if base != "torque_offset":
            low = max(low, 1e-9 if base.startswith("I") else 0.0)
        if not high > low:
            continue  # at its bound: the estimate is the value
        key = f"{base}[{('alpha', 'beta').index(joint)}]" if joint else base
        draws[f"params.{key}"] = {"uniform": [low, high]}
    return draws


def tune_spec(interval: FloatArray, plant: dict[str, Any], config: TuneConfig) -> dict[str, Any]:
    """The sweep spec (docs/SWEEPS.md) of ``tune``, without the choice's constraints.

    ``plant``: the identified plant (:func:`plant_values`); ``interval``: the 95 % intervals the plants are
    drawn within, in ``PARAMETER_NAMES`` order, shape (11, 2).
    """
    paper = FPDESOConfig().fuzzy
    model = {f"model.{name[7:]}": value for name, value in plant.items() if name.startswith("params.")}
    return {
        "name": "commissioning_tune",
        "controller": "fpdeso",
        "scenarios": ["case1"],
        "duration": config.duration,
        "fixed": model,
        "gains": {
            "fpdeso.fuzzy.kp0": {"grid": [[f * paper.kp0[0], f * paper.kp0[1]] for f in config.factors]},
            "fpdeso.fuzzy.kd0": {"grid": [[f * paper.kd0[0], f * paper.kd0[1]] for f in config.factors]},
        },
        "plant": plant,
        "plant_draws": {"count": config.draws, "seed": config.seed, "parameters": _draws(interval)},
        "objectives": ["RMS_alpha", "RMS_beta"],
        "statistic": "worst",
        "select": "RMS_alpha",
        "batch_size": 250,
    }


def run_tune(document: dict[str, Any], out: Path, config: TuneConfig) -> TuneResult:
    """Runs the sweep into ``out`` (smm-sweep's folder: Parquet, plots, report.md, chosen.yaml) and chooses.

    Raises:
        CommissioningError: The spec is refused, or no gain set is finite on every draw.
    """
    try:
        spec = parse_spec(document)
        run_sweep(spec, out, workers=config.workers)
        table = read_parts(out)
        first = analyse(spec, table, bounds={})
        middle = config.factors.index(1.0)  # the grid's product: k_p0 outer, k_d0 inner
        paper = middle * len(config.factors) + middle
        worst = first.statistics["worst"]
        columns = first.columns
        bound = {j: float(worst[paper, columns.index(f"case1.RMS_{j}")]) for j in ("alpha", "beta")}
        chosen_spec = parse_spec(
            {**document, "constraints": {f"RMS_{j}": {"<=": value} for j, value in bound.items()}}
        )
        result = analyse(chosen_spec, table)
        if result.chosen is None:
            raise CommissioningError("tune: no gain set stayed finite on every drawn plant")
        write_outputs(chosen_spec, result, table, out)
    except AnalysisError as error:
        raise CommissioningError(f"tune: {error}") from error
    run_id = result.chosen * len(chosen_spec.plant_draws) * len(chosen_spec.scenarios)
    settings = chosen_spec.settings(run_id)
    return TuneResult(chosen_spec, result, table, paper, parameters_sections(settings))
