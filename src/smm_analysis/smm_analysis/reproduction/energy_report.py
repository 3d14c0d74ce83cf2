"""Plot, report section and printout of the torque-noise study.

``python -m smm_analysis.reproduction.energy_report`` prints it.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from smm_analysis.reproduction.energy_study import (
    CUTOFF_HZ,
    EARLY_S,
    PAPER_STRUCTURE,
    EnergyStudy,
    chosen_setting,
    run_setting,
    sweep_settings,
    torque_terms,
)
from smm_analysis.reproduction.paper_values import PAPER_CASE2

__all__ = ["energy_section", "main", "write_energy_plot"]


def _ratios(
    numerator: tuple[float, float], denominator: tuple[float, float], scale: float = 1.0
) -> tuple[float, float]:
    return scale * numerator[0] / denominator[0], scale * numerator[1] / denominator[1]


def write_energy_plot(study: EnergyStudy, path: Path, *, dpi: int = 80) -> Path:
    """Case2 RMS against eps_u, one panel per joint: every setting, the default, FPD and the paper."""
    figure, axes = plt.subplots(1, 2, figsize=(10.0, 4.2))
    paper = PAPER_CASE2
    for joint, axis in enumerate(axes):
        finite = [p for p in study.points if math.isfinite(p.eps_u[joint]) and math.isfinite(p.rms[joint])]
        for source, marker in (("td", "o"), ("observer", "s")):
            chosen = [p for p in finite if p.setting.velocity_source == source]
            axis.scatter(
                [p.eps_u[joint] for p in chosen],
                [1e3 * p.rms[joint] for p in chosen],
                marker=marker,
                label=f"FPDESO, velocity from {source}",
            )
        fpd = {(p.fpd_eps_u[joint], p.fpd_rms[joint]) for p in finite}
        axis.scatter(
            [e for e, _ in fpd], [1e3 * r for _, r in fpd], marker="x", color="grey", label="FPD (same TD)"
        )
        default = next(p for p in study.points if p.setting == study.chosen)
        axis.scatter(
            [default.eps_u[joint]],
            [1e3 * default.rms[joint]],
            s=200,
            facecolors="none",
            edgecolors="red",
            linewidths=2,
            label="chosen default",
        )
        for name, marker in (("fpdeso", "*"), ("fpd", "P")):
            axis.scatter(
                [paper[name]["eps_u"][joint]],
                [1e3 * paper[name]["RMS"][joint]],
                marker=marker,
                s=120,
                color="black",
                label=f"paper {name.upper()} (Table 4)",
            )
        for point in finite:
            axis.annotate(
                point.setting.label.replace("observer", "obs"),
                (point.eps_u[joint], 1e3 * point.rms[joint]),
                fontsize=5,
            )
        axis.set_xscale("log")
        axis.set_xlabel("eps_u (N^2 m^2 s, log scale)")
        axis.set_ylabel("case2 RMS (mrad)")
        axis.set_title(("alpha", "beta")[joint])
        axis.grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=6)
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=dpi)
    plt.close(figure)
    return path


def _terms_table(study: EnergyStudy) -> list[str]:
    columns = (
        ("paper structure (TD velocity, h 1 ms)", study.paper_terms),
        (f"default ({study.chosen.label})", study.chosen_terms),
        ("default, no encoder noise", study.noise_free_terms),
    )
    lines = [
        "| term | "
        + " | ".join(f"{title}: eps_u / above {CUTOFF_HZ:g} Hz / du_rms" for title, _ in columns)
        + " |",
        "|---|" + "---|" * len(columns),
    ]
    for index, term in enumerate(study.paper_terms):
        cells = [
            f"{_fmt(terms[index].eps_u)} / {_fmt(terms[index].eps_u_above_cutoff)} / "
            f"{_fmt(terms[index].du_rms)}"
            for _, terms in columns
        ]
        lines.append(f"| {term.term} | " + " | ".join(cells) + " |")
    return lines


def _sweep_table(study: EnergyStudy) -> list[str]:
    lines = [
        "| setting | RMS (mrad) | eps_u | du_rms (N m) | FPD RMS (mrad), same TD | FPD eps_u, same TD | "
        "RMS below FPD (%) | eps_u / FPD's |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for point in study.points:
        mark = "**" if point.setting == study.chosen else ""
        fraction = _ratios(point.rms, point.fpd_rms, 100.0)
        reduction = (100.0 - fraction[0], 100.0 - fraction[1])
        ratio = _ratios(point.eps_u, point.fpd_eps_u)
        lines.append(
            f"| {mark}{point.setting.label}{mark} | {_fmt(point.rms, 1e3)} | {_fmt(point.eps_u)} | "
            f"{_fmt(point.du_rms)} | {_fmt(point.fpd_rms, 1e3)} | {_fmt(point.fpd_eps_u)} | "
            f"{_fmt(reduction)} | "
            f"{_fmt(ratio)} |"
        )
    return lines


def energy_section(study: EnergyStudy, plot: str | None) -> list[str]:
    """The report's section on torque noise (Markdown lines); ``plot``: relative path of the figure."""
    chosen = next(p for p in study.points if p.setting == study.chosen)
    paper = next((p for p in study.points if p.setting == PAPER_STRUCTURE), None)
    early = study.early_energy
    lines = [
        "## Torque noise and control energy (issue #15)",
        "",
        "Torque smoothness index: `du_rms`, the RMS of the commanded torque's increment per control step "
        "(N m; `smm_analysis.metrics.torque_increment_rms`, in metrics.json beside eps_u). eps_u cannot tell "
        "a smooth torque from a chattering one; du_rms can: white torque noise of std s gives sqrt(2) s, a "
        "smooth torque almost 0. Compare it at one control period (here 1 ms). A second view is each "
        f"term's energy above {CUTOFF_HZ:g} Hz (the references and the disturbance are below 1.2 Hz).",
        "",
        "### Where the noise comes from",
        "",
        "Case 2, FPDESO with the paper's gains; the torque split into the law's terms (internals "
        "`controller.*`; the feedback M u split into its fixed-gain position and velocity parts and the "
        "fuzzy schedule's share), alpha / beta. The terms add up to tau; the position and velocity parts of "
        "the start transient cancel in part, so their eps_u can exceed the total's. "
        "`python -m smm_analysis.reproduction.energy_study` prints the same figures.",
        "",
        *_terms_table(study),
        "",
    ]
    if paper is not None:
        lines += [
            f"With the paper's structure (q' from the TD, h = 1 ms) the velocity term M k_d0 e' carries the "
            f"noise: eps_u {_fmt(study.paper_terms[2].eps_u)} of the total "
            f"{_fmt(study.paper_terms[-1].eps_u)}, nearly all of it above {CUTOFF_HZ:g} Hz, and a torque "
            f"increment of {_fmt(study.paper_terms[2].du_rms)} "
            "N m per step. The TD at h = t is close to a finite difference, so 0.001 rad of encoder noise "
            "becomes about 1.4 rad/s of velocity noise, and k_d0 M = 110 x 0.071 N m s/rad turns it into "
            "torque noise of about 10 N m. The FLESO's x3 (disturbance term), the fuzzy schedule and the "
            "robust term's pure sign add "
            f"{_fmt(study.paper_terms[4].eps_u)}, {_fmt(study.paper_terms[3].eps_u)} and "
            f"{_fmt(study.paper_terms[5].eps_u)} N^2 m^2 s: small in energy, though the sign flips the "
            "robust "
            f"term by 2 b_d at random (du_rms {_fmt(study.paper_terms[5].du_rms)} N m).",
            "",
        ]
    lines += [
        "### Settings studied",
        "",
        "Each design of issue #15 is a parameter: `td.filter_factor` / `td.speed` (TD), "
        "`fpdeso.velocity_source` (`td` = the paper's eq. 26, `observer` = the FLESO's x2^, the usual ADRC "
        "choice), the FLESO bandwidth (`fleso.w0`, `fleso.k_w`, here scaled together) and "
        "`fpdeso.boundary_layer` (phi). Case 2, paper's gains, seed 0; FPD runs with the same TD, since the "
        "stack has one TD for every law. The chosen default is in bold.",
        "",
        *_sweep_table(study),
        "",
    ]
    if plot is not None:
        lines += [f"![case 2 RMS against eps_u]({plot})", ""]
    lines += [
        "### The chosen defaults and why",
        "",
        f"**{study.chosen.label}, phi = {study.chosen.boundary_layer:g}** (`fpdeso.velocity_source: "
        f"{study.chosen.velocity_source}`; the TD, the FLESO and every gain are the paper's / unchanged). "
        f"FPDESO's case-2 eps_u drops from {_fmt(paper.eps_u) if paper else '-'} to {_fmt(chosen.eps_u)} "
        f"and its torque increment from {_fmt(paper.du_rms) if paper else '-'} to {_fmt(chosen.du_rms)} N m, "
        f"for an RMS of {_fmt(chosen.rms, 1e3)} mrad (paper structure: "
        f"{_fmt(paper.rms, 1e3) if paper else '-'}), still far below FPD's {_fmt(chosen.fpd_rms, 1e3)}.",
        "",
        "* Velocity from the observer: the FLESO predicts with the model and the applied torque, so its x2^ "
        "needs no differentiation of the encoder and follows the true velocity with its own error dynamics "
        "(poles at -w, w = 9..48 rad/s); on the noise-free ramp it is exact (unit test). Its noise is what "
        "passes a third-order filter of bandwidth w, hundreds of times less than the TD's. That costs some "
        "RMS (the observer's lag against the +10 % inertia error and the disturbance), but the RMS stays "
        "well inside the 38 % claim.",
        "* The TD stays at h = t = 1 ms: with the observer's velocity the TD feeds only the position (to "
        "the FLESO and to k_p e); a larger h lowers the remaining torque increment (the position noise "
        "through M k_p0, about 0.45 N m per step) but adds phase lag: above 1.5 ms the RMS and the step "
        "overshoot grow (table), and the baselines, which share the TD, would change too.",
        "* A larger FLESO bandwidth (w x2, x3) tracks better but spends more; a smaller one (x 0.5) lags. "
        "The paper's bandwidth is kept: it is one of its gains.",
        "* The boundary layer phi changes eps_u by less than 0.1 % in every setting (the robust term is "
        "b_d = 0.06-0.09 N m); with the observer's velocity its sign seldom flips, so phi = 0 (the "
        "paper's sign) is kept. phi stays a parameter for a bench whose valve dislikes the switching.",
        "",
        "### The energy claim and its limit",
        "",
        f"With the defaults, FPDESO's case-2 eps_u is {_fmt(chosen.eps_u)} against FPD's "
        f"{_fmt(chosen.fpd_eps_u)} ({_fmt(_ratios(chosen.eps_u, chosen.fpd_eps_u))} x FPD's; "
        "paper 0.89 / 0.45): the claim is met and `--check` checks it. It holds against FPD with the "
        "stack's TD, and that FPD itself passes encoder noise into its torque (its du_rms is in the "
        "case 2 table). Given a smoother TD (h >= 1.5 ms, table), FPD spends less than FPDESO on alpha "
        "(and at 2 ms on beta by a hair): no setting of the study beats FPD's torque in that case. The "
        "reason is FPDESO's start: case 2 starts at rest with q_d' = (pi, 0.785 pi) rad/s, so e'(0) is "
        "large and k_d0 M = 7.8 / 6.2 N m s/rad gives a torque kick of about 25 / 15 N m for some 20 ms. "
        f"In the first {EARLY_S:g} s FPDESO spends {_fmt(early['fpdeso'])}, FPD "
        f"{_fmt(early['fpd'])}; after it FPDESO spends less than FPD (checked at h = 1 and 2 ms). "
        "The paper's gains fix that kick; a smooth start (a reference starting at zero velocity) would "
        "remove it, but the scenario is the paper's.",
        "",
    ]
    return lines


def _fmt(pair: tuple[float, float], scale: float = 1.0) -> str:
    return f"{pair[0] * scale:.3g} / {pair[1] * scale:.3g}"


def main(argv: Sequence[str] | None = None) -> int:
    """Prints the term split of the paper's structure and of the defaults, then the sweep."""
    parser = argparse.ArgumentParser(
        prog="python -m smm_analysis.reproduction.energy_report", description=__doc__
    )
    parser.add_argument("--seed", type=int, default=0)
    options = parser.parse_args(argv)
    for setting in (PAPER_STRUCTURE, chosen_setting()):
        print(
            f"case2 torque terms, {setting.label} (alpha / beta): eps_u, eps_u above {CUTOFF_HZ:g} Hz, du_rms"
        )
        run = run_setting(setting, seed=options.seed, record_internals=True)
        for term in torque_terms(run, setting.fpdeso_config()):
            print(
                f"  {term.term:<38} {_fmt(term.eps_u):>20} {_fmt(term.eps_u_above_cutoff):>20} "
                f"{_fmt(term.du_rms):>20}"
            )
    print("case2 sweep: RMS (mrad), eps_u, du_rms (N m) alpha / beta; FPD eps_u with the same TD")
    for point in sweep_settings(seed=options.seed):
        print(
            f"  {point.setting.label:<32} {_fmt(point.rms, 1e3):>18} {_fmt(point.eps_u):>18} "
            f"{_fmt(point.du_rms):>18} {_fmt(point.fpd_eps_u):>18}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
