"""Truth recovery on the simulator: a plant drawn away from the paper's values, excited, identified.

The experiment of docs/IDENTIFICATION.md ("Truth recovery"), used by its tests and by
``python -m smm_analysis.identification.truth`` (the 20-seed interval coverage; slow).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from smm_sim.plant import PlantConfig

from smm_analysis.closed_loop import Trajectory, run_closed_loop
from smm_analysis.identification.data import FilterSettings, PreparedRun, prepare_run
from smm_analysis.identification.estimate import EstimationSettings, Identification, identify
from smm_analysis.identification.regressor import PARAMETER_NAMES, parameter_vector
from smm_analysis.scenarios import get_scenario
from smm_dynamics import SMMParameters

__all__ = ["Recovery", "draw_plant", "prepare_trajectory", "recover", "simulate_excitation"]

FloatArray = NDArray[np.float64]
#: Encoder resolution of the noisy case (counts per revolution).
NOISY_COUNTS = 2**20


def draw_plant(seed: int, *, frictionless: bool = False) -> SMMParameters:
    """Plant parameters drawn away from the paper's: inertias and lever x U(0.8, 0.95) or U(1.05, 1.3).

    Friction: viscous U(0.05, 0.3) N m s/rad, Coulomb U(0.03, 0.15) N m, offset +-U(0.03, 0.1) N m; with
    ``frictionless`` the Coulomb levels and offsets are 0 (the zero-truth case).
    """
    rng = np.random.default_rng(10_000 + seed)
    nominal = SMMParameters()

    def away(value: float) -> float:
        factor = rng.uniform(0.8, 0.95) if rng.random() < 0.5 else rng.uniform(1.05, 1.3)
        return float(value * factor)

    def pair(low: float, high: float, signed: bool = False) -> tuple[float, float]:
        values = rng.uniform(low, high, 2) * (rng.choice([-1.0, 1.0], 2) if signed else 1.0)
        return float(values[0]), float(values[1])

    viscous = pair(0.05, 0.3)
    coulomb = pair(0.03, 0.15)
    offset = pair(0.03, 0.1, signed=True)
    return dataclasses.replace(
        nominal,
        I11=away(nominal.I11),
        I22=away(nominal.I22),
        I44=away(nominal.I44),
        I55=away(nominal.I55),
        mass_lever=away(nominal.mass_lever),
        viscous_friction=viscous,
        coulomb_friction=(0.0, 0.0) if frictionless else coulomb,
        torque_offset=(0.0, 0.0) if frictionless else offset,
    )


def simulate_excitation(
    plant: SMMParameters, *, seed: int, noisy: bool, duration: float | None = None
) -> Trajectory:
    """FPDESO (nominal model) tracking the ``excite`` scenario's reference on ``plant``, lockstep, offline.

    Noisy: encoder noise as in case 2 (std 0.001 rad) and 2^20 counts per revolution.
    """
    scenario = get_scenario("excite")
    if duration is not None:
        scenario = scenario.with_duration(duration)
    noise = scenario.noise_std if noisy else (0.0, 0.0)
    config = PlantConfig(
        params=plant, noise_std=noise, encoder_counts_per_rev=NOISY_COUNTS if noisy else 0, seed=seed
    )
    return run_closed_loop(scenario, "fpdeso", seed=seed, plant_config=config, record_internals=False)


def prepare_trajectory(name: str, run: Trajectory, settings: FilterSettings | None = None) -> PreparedRun:
    """A closed-loop run as a bag holds it: measured positions, effort = torque before each stamp."""
    effort = np.vstack([np.zeros((1, 2)), run.applied_torque[:-1]])
    return prepare_run(name, run.t_ns, run.measured_position, effort, settings, command=run.command_torque)


@dataclass(frozen=True)
class Recovery:
    """One truth-recovery run.

    Attributes:
        seed: Seed of the plant draw and of the noise.
        truth: The plant's parameters.
        result: The identification.
        error: Estimate minus truth per parameter, shape (11,).
        relative: |error| / |truth|, or |error| / largest torque where the truth is 0, shape (11,).
        covered: Whether each 95 % interval holds the truth, shape (11,).
    """

    seed: int
    truth: SMMParameters
    result: Identification
    error: FloatArray
    relative: FloatArray
    covered: NDArray[np.bool_]


def recover(seed: int, *, noisy: bool, frictionless: bool = False, bootstrap: int = 200) -> Recovery:
    """Draws a plant, excites it in closed loop, identifies it and compares with the truth."""
    truth = draw_plant(seed, frictionless=frictionless)
    run = simulate_excitation(truth, seed=seed, noisy=noisy)
    result = identify(
        [prepare_trajectory(f"seed {seed}", run)], settings=EstimationSettings(bootstrap=bootstrap)
    )
    true_theta = parameter_vector(truth)
    error = result.theta - true_theta
    denominator = np.where(true_theta != 0.0, np.abs(true_theta), result.largest_torque)
    covered = (result.interval[:, 0] <= true_theta) & (true_theta <= result.interval[:, 1])
    return Recovery(seed, truth, result, error, np.abs(error) / denominator, covered)


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the truth recovery over seeds and prints the worst errors and the interval coverage."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--seeds", type=int, default=20, help="number of seeds (default 20)")
    parser.add_argument("--noise-free", action="store_true", help="no encoder noise, no quantisation")
    args = parser.parse_args(argv)
    recoveries = []
    for seed in range(args.seeds):
        recovery = recover(seed, noisy=not args.noise_free)
        recoveries.append(recovery)
        print(
            f"seed {seed:2d}: largest error {100 * recovery.relative.max():.2f} % "
            f"({PARAMETER_NAMES[int(recovery.relative.argmax())]}), intervals holding the truth "
            f"{int(recovery.covered.sum())}/{len(PARAMETER_NAMES)}",
            file=sys.stderr,
            flush=True,
        )
    covered = np.sum([recovery.covered for recovery in recoveries], axis=0)
    worst = np.max([recovery.relative for recovery in recoveries], axis=0)
    print("| parameter | largest error (%) | seeds whose 95 % interval holds the truth |")
    print("|---|---|---|")
    for name, error, count in zip(PARAMETER_NAMES, worst, covered, strict=True):
        print(f"| {name} | {100 * error:.2f} | {int(count)}/{args.seeds} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
