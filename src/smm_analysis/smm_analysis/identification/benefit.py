"""Does the identified model pay? Case 2 with FPDESO on the nominal and on the identified model.

The experiment of docs/IDENTIFICATION.md ("The loop closes"): the ``excite`` scenario is run on the case 2
plant (inertias +10 %), the plant identified from it, then case 2 run (same seed, lockstep, offline) with
the nominal model, the identified model, and the identified model with its friction compensated.
``python -m smm_analysis.identification.benefit`` prints the table of the docs.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from smm_controller.fleso import FLESOConfig
from smm_controller.fpdeso import FPDESOConfig, FPDESOController

from smm_analysis.closed_loop import Trajectory, run_closed_loop, scenario_plant_config
from smm_analysis.identification.estimate import identify
from smm_analysis.identification.truth import prepare_trajectory
from smm_analysis.lumped import trajectory_lumped_disturbance
from smm_analysis.scenarios import get_scenario
from smm_dynamics import SMMParameters

__all__ = ["ModelRun", "compare_models", "identified_case2_model"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ModelRun:
    """Case 2 with one controller model.

    Attributes:
        label: Which model.
        tracking_rms: RMS of q_d - q per joint (rad).
        estimate_rms: RMS of the FLESO's estimate xi~ per joint (N m).
        model_error_rms: RMS of the true lumped disturbance's model-error part per joint (N m).
        run: The run.
    """

    label: str
    tracking_rms: FloatArray
    estimate_rms: FloatArray
    model_error_rms: FloatArray
    run: Trajectory


def identified_case2_model(seed: int = 0) -> SMMParameters:
    """The model identified from the ``excite`` scenario (case 2 plant) with FPDESO on the nominal model."""
    excitation = run_closed_loop("excite", "fpdeso", seed=seed, record_internals=False)
    return identify([prepare_trajectory("excite", excitation)]).params


def _rms(values: FloatArray) -> FloatArray:
    return np.asarray(np.sqrt(np.mean(values**2, axis=0)), dtype=np.float64)


def _case2(
    label: str, model: SMMParameters, seed: int, *, compensate: bool, duration: float | None
) -> ModelRun:
    spec = get_scenario("case2") if duration is None else get_scenario("case2").with_duration(duration)
    extra = (
        {
            "controller": FPDESOController(FPDESOConfig(compensate_friction=True), model),
            "fleso_config": FLESOConfig(compensate_friction=True),
        }
        if compensate
        else {}
    )
    # The plant is case 2's (the paper's parameters, inertias +10 %) whatever the controller's model.
    plant = scenario_plant_config(spec, seed=seed, params=SMMParameters())
    run = run_closed_loop(
        spec,
        "fpdeso",
        seed=seed,
        model_params=model,
        plant_config=plant,
        **extra,  # type: ignore[arg-type]
    )
    parts = trajectory_lumped_disturbance(run, compensate_friction=compensate)
    return ModelRun(
        label, _rms(run.tracking_error), _rms(run.disturbance_estimate), _rms(parts.model_error), run
    )


def compare_models(
    identified: SMMParameters, *, seed: int = 0, duration: float | None = None
) -> tuple[ModelRun, ModelRun, ModelRun]:
    """Case 2 with the nominal model, the identified one, and the identified one compensating its friction."""
    return (
        _case2("nominal (paper)", SMMParameters(), seed, compensate=False, duration=duration),
        _case2("identified", identified, seed, compensate=False, duration=duration),
        _case2("identified, friction compensated", identified, seed, compensate=True, duration=duration),
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Prints the comparison table of docs/IDENTIFICATION.md."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, help="write lumped_disturbance.png here")
    args = parser.parse_args(argv)
    identified = identified_case2_model(args.seed)
    runs = compare_models(identified, seed=args.seed)
    print(f"identified: {identified}")
    print(
        "| model | RMS error alpha (mrad) | RMS error beta (mrad) | RMS xi~ alpha (N m) | RMS xi~ beta (N m) "
        "| RMS model error alpha (N m) | RMS model error beta (N m) |"
    )
    print("|---|---|---|---|---|---|---|")
    for run in runs:
        print(
            f"| {run.label} | {1e3 * run.tracking_rms[0]:.3f} | {1e3 * run.tracking_rms[1]:.3f} | "
            f"{run.estimate_rms[0]:.3f} | {run.estimate_rms[1]:.3f} | {run.model_error_rms[0]:.3f} | "
            f"{run.model_error_rms[1]:.3f} |"
        )
    if args.out is not None:
        from smm_analysis.identification.plots import lumped_figure  # noqa: PLC0415  (matplotlib)

        args.out.mkdir(parents=True, exist_ok=True)
        chosen = [
            (run.label, run.run, trajectory_lumped_disturbance(run.run, compensate_friction=index == 2))
            for index, run in enumerate(runs)
        ]
        print(f"wrote {lumped_figure(chosen, args.out / 'lumped_disturbance.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
