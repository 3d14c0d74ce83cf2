"""Sweep of the tracking differentiator's (sigma, h) against case2 tracking RMS with FPDESO (SPEC section 4).

The TD step t is the control period; sigma (speed factor, rad/s^2) and h (filter factor, s, >= t) are
swept over a grid, the same value on both joints, and each pair is scored by the case2 RMS tracking
error of FPDESO (true plant position, eq. 44) per joint and by their sum.

Run ``python -m smm_analysis.reproduction.tune_td`` for the default grid (prints the table and the best pair).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from smm_analysis.closed_loop import DEFAULT_CONTROL_PERIOD, run_closed_loop
from smm_analysis.errors import AnalysisError, ClosedLoopDivergedError
from smm_analysis.metrics import control_energy, rms_error
from smm_analysis.scenarios import SCENARIOS, Scenario
from smm_controller import TrackingDifferentiatorConfig

__all__ = [
    "DEFAULT_FILTER_FACTORS",
    "DEFAULT_SPEEDS",
    "TDSweepPoint",
    "best_point",
    "chosen_point",
    "format_table",
    "main",
    "sweep_td",
]

DEFAULT_SPEEDS: tuple[float, ...] = (1.0e3, 1.0e4, 1.0e5, 1.0e6)
"""Speed factors sigma of the default grid (rad/s^2)."""

DEFAULT_FILTER_FACTORS: tuple[float, ...] = (0.001, 0.0015, 0.002, 0.003, 0.005, 0.008)
"""Filter factors h of the default grid (s)."""


@dataclass(frozen=True)
class TDSweepPoint:
    """Score of one (sigma, h) pair.

    Attributes:
        speed: sigma (rad/s^2), both joints.
        filter_factor: h (s), both joints.
        rms_alpha: case2 RMS tracking error of alpha (rad); inf if the loop went unstable.
        rms_beta: case2 RMS tracking error of beta (rad); inf if the loop went unstable.
        energy_alpha: Control energy eps_u of alpha (N^2 m^2 s); inf if the loop went unstable.
        energy_beta: Control energy eps_u of beta (N^2 m^2 s); inf if the loop went unstable.
    """

    speed: float
    filter_factor: float
    rms_alpha: float
    rms_beta: float
    energy_alpha: float = math.inf
    energy_beta: float = math.inf

    @property
    def rms_sum(self) -> float:
        """rms_alpha + rms_beta (rad), the score minimised."""
        return self.rms_alpha + self.rms_beta


def sweep_td(
    speeds: Sequence[float] = DEFAULT_SPEEDS,
    filter_factors: Sequence[float] = DEFAULT_FILTER_FACTORS,
    *,
    scenario: Scenario | None = None,
    controller_name: str = "fpdeso",
    seed: int = 0,
    control_period: float = DEFAULT_CONTROL_PERIOD,
    progress: Callable[[TDSweepPoint], None] | None = None,
) -> list[TDSweepPoint]:
    """Runs the closed loop for every (sigma, h) of the grid.

    Args:
        speeds: sigma values (rad/s^2), > 0.
        filter_factors: h values (s), >= control_period.
        scenario: Scenario to score on (default: case2).
        controller_name: Controller of the chain (default FPDESO).
        seed: Noise seed.
        control_period: Control period = TD step t (s).
        progress: Called with each point as soon as it is computed.

    Returns:
        One point per pair, sigma-major order.

    Raises:
        AnalysisError: An empty grid or an h below the control period.
    """
    if not speeds or not filter_factors:
        raise AnalysisError("the sweep needs at least one speed and one filter factor")
    too_small = [h for h in filter_factors if h < control_period]
    if too_small:
        raise AnalysisError(f"filter factors {too_small} are below the control period {control_period} s")
    spec = scenario if scenario is not None else SCENARIOS["case2"]
    points: list[TDSweepPoint] = []
    for speed in speeds:
        for factor in filter_factors:
            td = TrackingDifferentiatorConfig(speed=(speed, speed), filter_factor=(factor, factor))
            try:
                run = run_closed_loop(
                    spec,
                    controller_name,
                    seed=seed,
                    control_period=control_period,
                    td_config=td,
                    record_internals=False,
                )
            except ClosedLoopDivergedError:
                point = TDSweepPoint(speed, factor, math.inf, math.inf, math.inf, math.inf)
            else:
                error = run.tracking_error
                point = TDSweepPoint(
                    speed=speed,
                    filter_factor=factor,
                    rms_alpha=rms_error(run.t_ns, error[:, 0]),
                    rms_beta=rms_error(run.t_ns, error[:, 1]),
                    energy_alpha=control_energy(run.t_ns, run.command_torque[:, 0]),
                    energy_beta=control_energy(run.t_ns, run.command_torque[:, 1]),
                )
            points.append(point)
            if progress is not None:
                progress(point)
    return points


def best_point(points: Sequence[TDSweepPoint]) -> TDSweepPoint:
    """The point with the smallest rms_alpha + rms_beta.

    Sums equal to 12 significant digits are ties (on the sigma plateau they differ only by round-off),
    broken by the smaller h, then the smaller sigma, so the answer does not depend on round-off.
    """
    if not points:
        raise AnalysisError("no sweep points")
    return min(points, key=lambda point: (float(f"{point.rms_sum:.12g}"), point.filter_factor, point.speed))


def chosen_point(points: Sequence[TDSweepPoint], tolerance: float = 1e-3) -> TDSweepPoint:
    """The recommended pair: the best h, and the middle sigma of the plateau at that h.

    Once sigma is large enough for the TD to stay linear, the RMS no longer depends on it, so several
    sigma tie. Among the points at the best h whose RMS sum is within ``tolerance`` (relative) of the best,
    the middle one in sigma is chosen: it keeps a margin both to TD saturation (sigma too small) and to
    an unnecessarily narrow nonlinear zone (sigma larger than needed).

    Args:
        points: Sweep points.
        tolerance: Relative tolerance on the RMS sum that counts as a tie.

    Returns:
        The recommended point.
    """
    best = best_point(points)
    ties = sorted(
        (
            point
            for point in points
            if point.filter_factor == best.filter_factor and point.rms_sum <= best.rms_sum * (1.0 + tolerance)
        ),
        key=lambda point: point.speed,
    )
    return ties[len(ties) // 2]


def format_table(points: Sequence[TDSweepPoint], *, energy: bool = False) -> str:
    """Markdown table: rows sigma, columns h; cells 'alpha / beta'.

    Args:
        points: Sweep points.
        energy: Tabulate the control energy eps_u (N^2 m^2 s) instead of the RMS error (mrad).

    Returns:
        The table; the best pair (lowest RMS sum) in bold.
    """
    speeds = sorted({point.speed for point in points})
    factors = sorted({point.filter_factor for point in points})
    lookup = {(point.speed, point.filter_factor): point for point in points}
    best = best_point(points)
    header = "| sigma (rad/s^2) \\ h (ms) | " + " | ".join(f"{1e3 * h:g}" for h in factors) + " |"
    lines = [header, "|---|" + "---|" * len(factors)]
    for speed in speeds:
        cells = []
        for factor in factors:
            point = lookup.get((speed, factor))
            if point is None:
                cells.append("")
                continue
            if energy:
                cell = f"{point.energy_alpha:.4g} / {point.energy_beta:.4g}"
            else:
                cell = f"{1e3 * point.rms_alpha:.3f} / {1e3 * point.rms_beta:.3f}"
            cells.append(f"**{cell}**" if point is best else cell)
        lines.append(f"| {speed:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``python -m smm_analysis.reproduction.tune_td``; returns the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--speeds", type=float, nargs="+", default=list(DEFAULT_SPEEDS), help="sigma values (rad/s^2)"
    )
    parser.add_argument(
        "--filter-factors", type=float, nargs="+", default=list(DEFAULT_FILTER_FACTORS), help="h values (s)"
    )
    parser.add_argument("--seed", type=int, default=0, help="noise seed")
    parser.add_argument("--duration", type=float, help="shorten case2 to this length (s), for a quick look")
    args = parser.parse_args(argv)
    try:
        scenario = (
            SCENARIOS["case2"] if args.duration is None else SCENARIOS["case2"].with_duration(args.duration)
        )
        points = sweep_td(
            args.speeds,
            args.filter_factors,
            scenario=scenario,
            seed=args.seed,
            progress=lambda p: print(
                f"sigma {p.speed:g} h {1e3 * p.filter_factor:g} ms: RMS {1e3 * p.rms_alpha:.3f} / "
                f"{1e3 * p.rms_beta:.3f} mrad",
                flush=True,
            ),
        )
    except (AnalysisError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print()
    print("case2 FPDESO RMS tracking error alpha / beta (mrad):")
    print(format_table(points))
    print("\ncase2 FPDESO control energy eps_u alpha / beta (N^2 m^2 s):")
    print(format_table(points, energy=True))
    best = best_point(points)
    chosen = chosen_point(points)
    print(
        f"\nbest: sigma = {best.speed:g} rad/s^2, h = {best.filter_factor:g} s "
        f"(RMS {1e3 * best.rms_alpha:.3f} / {1e3 * best.rms_beta:.3f} mrad)"
    )
    print(
        f"chosen: sigma = {chosen.speed:g} rad/s^2, h = {chosen.filter_factor:g} s "
        "(middle of the sigma plateau within 0.1 % of the best RMS sum)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
