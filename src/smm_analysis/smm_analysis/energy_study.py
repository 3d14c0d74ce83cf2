"""Where FPDESO's case2 torque noise comes from, and the settings that remove it (issue #15).

Two tools over the offline loop, both on the paper's gains:

* :func:`torque_terms`: the commanded torque of an FPDESO run split into the law's terms (internals
  ``controller.*``), the feedback M u further split into M k_p0 e (position), M k_d0 e' (velocity) and
  M (dk_p e + dk_d e') (fuzzy schedule); each term's eps_u, its energy above :data:`CUTOFF_HZ` and its
  torque increment (``du_rms``).
* :func:`sweep_settings`: case2 RMS, eps_u and du_rms of FPDESO over :data:`DEFAULT_SETTINGS` (velocity
  source, TD filter factor, FLESO bandwidth, boundary layer), each beside FPD run with the same TD.

Run ``python -m smm_analysis.energy_study`` to print both. docs/REPRODUCTION.md, "Torque noise", shows them.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
from numpy.typing import NDArray

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from smm_controller.fpdeso import FPDESOConfig, FPDESOController

from smm_analysis.closed_loop import Trajectory, run_closed_loop
from smm_analysis.errors import ClosedLoopDivergedError
from smm_analysis.metrics import control_energy, rms_error, torque_increment_rms
from smm_analysis.paper_values import PAPER_CASE2
from smm_analysis.scenarios import Scenario, get_scenario
from smm_controller import FLESOConfig, TrackingDifferentiatorConfig
from smm_dynamics import SMMParameters, mass_matrix

__all__ = [
    "CUTOFF_HZ",
    "DEFAULT_SETTINGS",
    "PAPER_STRUCTURE",
    "EnergyPoint",
    "EnergySetting",
    "EnergyStudy",
    "TermEnergy",
    "chosen_setting",
    "energy_above",
    "energy_section",
    "main",
    "run_energy_study",
    "run_setting",
    "sweep_settings",
    "torque_terms",
    "write_energy_plot",
]

FloatArray = NDArray[np.float64]

CUTOFF_HZ = 20.0
"""Cut-off of the high-frequency torque energy (Hz): the paper's references and disturbance are <= 1.2 Hz
and the closed loop's bandwidth about 10 Hz, so torque above 20 Hz is noise a valve should not see."""


@dataclass(frozen=True)
class EnergySetting:
    """One design setting of FPDESO's signal path (the paper's gains are kept).

    Attributes:
        velocity_source: ``"td"`` (paper) or ``"observer"`` (FLESO x2^).
        filter_factor: TD filter factor h (s), both joints.
        speed: TD speed sigma (rad/s^2), both joints.
        fleso_scale: Factor on the FLESO's w0 and k_w (1 = the paper's bandwidth).
        boundary_layer: Robust-term boundary layer phi, both joints (0 = the paper's sign).
    """

    velocity_source: str = "observer"
    filter_factor: float = 0.001
    speed: float = 1.0e5
    fleso_scale: float = 1.0
    boundary_layer: float = 0.0

    @property
    def label(self) -> str:
        """Short description, e.g. ``observer, h 1 ms``."""
        text = f"{self.velocity_source}, h {self.filter_factor * 1e3:g} ms"
        if self.speed != 1.0e5:
            text += f", sigma {self.speed:g}"
        if self.fleso_scale != 1.0:
            text += f", w x{self.fleso_scale:g}"
        if self.boundary_layer != 0.0:
            text += f", phi {self.boundary_layer:g}"
        return text

    def td_config(self) -> TrackingDifferentiatorConfig:
        """The TD of this setting."""
        return TrackingDifferentiatorConfig(
            speed=(self.speed, self.speed), filter_factor=(self.filter_factor, self.filter_factor)
        )

    def fleso_config(self) -> FLESOConfig:
        """The FLESO of this setting (the paper's, bandwidth scaled)."""
        paper = FLESOConfig()
        scale = self.fleso_scale
        return dataclasses.replace(
            paper,
            w0=(paper.w0[0] * scale, paper.w0[1] * scale),
            k_w=(paper.k_w[0] * scale, paper.k_w[1] * scale),
        )

    def fpdeso_config(self) -> FPDESOConfig:
        """The law of this setting (the paper's gains)."""
        phi = self.boundary_layer
        return FPDESOConfig(velocity_source=self.velocity_source, boundary_layer=(phi, phi))


PAPER_STRUCTURE = EnergySetting(velocity_source="td")
"""The paper's structure with the former defaults: TD velocity, h = 1 ms, pure sign."""

DEFAULT_SETTINGS: tuple[EnergySetting, ...] = (
    *(EnergySetting("td", h) for h in (0.001, 0.0015, 0.002, 0.003, 0.005)),
    EnergySetting("td", 0.001, boundary_layer=1.0),
    *(EnergySetting("observer", h) for h in (0.001, 0.0015, 0.002, 0.003, 0.005)),
    EnergySetting("observer", 0.001, speed=1.0e3),
    *(EnergySetting("observer", 0.001, fleso_scale=scale) for scale in (0.5, 2.0, 3.0)),
    *(EnergySetting("observer", 0.001, boundary_layer=phi) for phi in (0.1, 1.0)),
)
"""The settings studied: each design of issue #15 varied around the paper's structure and the default."""


def chosen_setting() -> EnergySetting:
    """The stack's defaults as a setting (TD, FLESO and FPDESO defaults of ``smm_controller``)."""
    td, law = TrackingDifferentiatorConfig(), FPDESOConfig()
    if td.speed[0] != td.speed[1] or td.filter_factor[0] != td.filter_factor[1]:
        raise ValueError("the study's settings use one TD value for both joints")
    return EnergySetting(
        velocity_source=law.velocity_source,
        filter_factor=td.filter_factor[0],
        speed=td.speed[0],
        boundary_layer=law.boundary_layer[0],
    )


@dataclass(frozen=True)
class EnergyPoint:
    """Case2 figures of one setting, per joint (alpha, beta); inf where the loop went unstable.

    Attributes:
        setting: The setting.
        rms: FPDESO tracking RMS (rad).
        eps_u: FPDESO control energy (N^2 m^2 s).
        du_rms: FPDESO torque increment RMS (N m per step).
        fpd_eps_u: FPD's control energy with the same TD (N^2 m^2 s).
        fpd_rms: FPD's tracking RMS with the same TD (rad).
    """

    setting: EnergySetting
    rms: tuple[float, float]
    eps_u: tuple[float, float]
    du_rms: tuple[float, float]
    fpd_eps_u: tuple[float, float]
    fpd_rms: tuple[float, float]


def _pair(function: Callable[[int], float]) -> tuple[float, float]:
    return function(0), function(1)


_UNSTABLE = (math.inf, math.inf)


def _fpd_figures(
    scenario: Scenario, td: TrackingDifferentiatorConfig, seed: int
) -> tuple[tuple[float, float], ...]:
    try:
        run = run_closed_loop(scenario, "fpd", seed=seed, td_config=td, record_internals=False)
    except ClosedLoopDivergedError:
        return _UNSTABLE, _UNSTABLE
    return (
        _pair(lambda j: control_energy(run.t_ns, run.command_torque[:, j])),
        _pair(lambda j: rms_error(run.t_ns, run.tracking_error[:, j])),
    )


def run_setting(
    setting: EnergySetting,
    *,
    scenario: Scenario | str = "case2",
    seed: int = 0,
    record_internals: bool = False,
) -> Trajectory:
    """FPDESO with the paper's gains and ``setting``'s signal path on ``scenario``."""
    spec = get_scenario(scenario) if isinstance(scenario, str) else scenario
    return run_closed_loop(
        spec,
        "fpdeso",
        seed=seed,
        td_config=setting.td_config(),
        fleso_config=setting.fleso_config(),
        controller=FPDESOController(setting.fpdeso_config(), SMMParameters()),
        record_internals=record_internals,
    )


def _figures(run: Trajectory) -> tuple[tuple[float, float], ...]:
    """(RMS, eps_u, du_rms) of a run, each per joint."""
    t_ns, torque = run.t_ns, run.command_torque
    return (
        _pair(lambda j: rms_error(t_ns, run.tracking_error[:, j])),
        _pair(lambda j: control_energy(t_ns, torque[:, j])),
        _pair(lambda j: torque_increment_rms(torque[:, j])),
    )


def sweep_settings(
    settings: Sequence[EnergySetting] = DEFAULT_SETTINGS,
    *,
    seed: int = 0,
    progress: Callable[[int, int, EnergySetting], None] | None = None,
) -> list[EnergyPoint]:
    """Case2 figures of every setting (FPD runs once per distinct TD)."""
    scenario = get_scenario("case2")
    fpd: dict[TrackingDifferentiatorConfig, tuple[tuple[float, float], ...]] = {}
    points = []
    for index, setting in enumerate(settings):
        if progress is not None:
            progress(index, len(settings), setting)
        td = setting.td_config()
        if td not in fpd:
            fpd[td] = _fpd_figures(scenario, td, seed)
        try:
            rms, eps_u, du_rms = _figures(run_setting(setting, scenario=scenario, seed=seed))
        except ClosedLoopDivergedError:
            rms = eps_u = du_rms = _UNSTABLE
        points.append(EnergyPoint(setting, rms, eps_u, du_rms, fpd[td][0], fpd[td][1]))
    return points


def energy_above(t_ns: NDArray[np.int64], torque: FloatArray, cutoff_hz: float = CUTOFF_HZ) -> float:
    """Part of integral tau^2 dt above ``cutoff_hz`` (N^2 m^2 s; Parseval, uniformly sampled torque)."""
    dt = float(np.mean(np.diff(t_ns))) / 1e9
    spectrum = np.fft.rfft(torque)
    frequencies = np.fft.rfftfreq(torque.size, dt)
    weights = np.where((frequencies == 0.0) | (frequencies == frequencies[-1]), 1.0, 2.0)
    above = frequencies > cutoff_hz
    return float(np.sum(weights[above] * np.abs(spectrum[above]) ** 2) * dt / torque.size)


@dataclass(frozen=True)
class TermEnergy:
    """One torque term of an FPDESO run, per joint (alpha, beta).

    Attributes:
        term: Name of the term.
        eps_u: integral term^2 dt (N^2 m^2 s).
        eps_u_above_cutoff: Its part above :data:`CUTOFF_HZ` (N^2 m^2 s).
        du_rms: Its increment RMS (N m per step).
    """

    term: str
    eps_u: tuple[float, float]
    eps_u_above_cutoff: tuple[float, float]
    du_rms: tuple[float, float]


def torque_terms(run: Trajectory, config: FPDESOConfig) -> list[TermEnergy]:
    """The torque of an FPDESO run (recorded internals) split into its terms; the last row is tau."""
    internals = run.internals
    velocity = internals["fleso.x2_hat"] if config.velocity_source == "observer" else internals["td.x2"]
    e = run.reference[:, 0, :] - internals["td.x1"]
    e_dot = run.reference[:, 1, :] - velocity
    fuzzy = config.fuzzy
    mass = mass_matrix(internals["td.x1"], run.model_params)
    position = np.einsum("kij,kj->ki", mass, np.array(fuzzy.kp0) * e)
    damping = np.einsum("kij,kj->ki", mass, np.array(fuzzy.kd0) * e_dot)
    terms: Mapping[str, FloatArray] = {
        "feedforward M q_d'' + C q' + G": internals["controller.feedforward"],
        "position M k_p0 e": position,
        "velocity M k_d0 e'": damping,
        "fuzzy schedule M (dk_p e + dk_d e')": internals["controller.feedback"] - position - damping,
        "disturbance xi~ = -M x3^": internals["controller.disturbance"],
        "robust -v": -internals["controller.robust"],
        "total tau": run.command_torque,
    }
    return [_term_energy(term, run.t_ns, values) for term, values in terms.items()]


def _term_energy(term: str, t_ns: NDArray[np.int64], values: FloatArray) -> TermEnergy:
    return TermEnergy(
        term,
        _pair(lambda j: control_energy(t_ns, values[:, j])),
        _pair(lambda j: energy_above(t_ns, values[:, j])),
        _pair(lambda j: torque_increment_rms(values[:, j])),
    )


@dataclass(frozen=True)
class EnergyStudy:
    """The study of issue #15: the sweep and the term split of the paper's structure and of the defaults.

    Attributes:
        points: Case2 figures per setting (the chosen setting among them).
        chosen: The stack's defaults as a setting.
        paper_terms: Torque terms of :data:`PAPER_STRUCTURE` on case2.
        chosen_terms: Torque terms of ``chosen`` on case2.
        noise_free_terms: Torque terms of ``chosen`` on case2 without encoder noise (the floor).
        early_energy: eps_u of FPDESO (chosen) and FPD in the first :data:`EARLY_S` s of case2, per joint.
    """

    points: tuple[EnergyPoint, ...]
    chosen: EnergySetting
    paper_terms: tuple[TermEnergy, ...]
    chosen_terms: tuple[TermEnergy, ...]
    noise_free_terms: tuple[TermEnergy, ...]
    early_energy: Mapping[str, tuple[float, float]]


EARLY_S = 0.2
"""Length of the start transient whose energy the study reports separately (s)."""


def run_energy_study(
    *, seed: int = 0, progress: Callable[[int, int, EnergySetting], None] | None = None
) -> EnergyStudy:
    """Runs the sweep (adding the chosen setting if it is not in it) and the term splits."""
    chosen = chosen_setting()
    settings = DEFAULT_SETTINGS if chosen in DEFAULT_SETTINGS else (*DEFAULT_SETTINGS, chosen)
    points = sweep_settings(settings, seed=seed, progress=progress)
    case2 = get_scenario("case2")
    quiet = dataclasses.replace(case2, noise_std=(0.0, 0.0))
    chosen_run = run_setting(chosen, seed=seed, record_internals=True)
    fpd_run = run_closed_loop(case2, "fpd", seed=seed, td_config=chosen.td_config(), record_internals=False)
    early = round(EARLY_S / chosen_run.control_period) + 1
    return EnergyStudy(
        points=tuple(points),
        chosen=chosen,
        paper_terms=tuple(
            torque_terms(
                run_setting(PAPER_STRUCTURE, seed=seed, record_internals=True),
                PAPER_STRUCTURE.fpdeso_config(),
            )
        ),
        chosen_terms=tuple(torque_terms(chosen_run, chosen.fpdeso_config())),
        noise_free_terms=tuple(
            torque_terms(
                run_setting(chosen, scenario=quiet, seed=seed, record_internals=True), chosen.fpdeso_config()
            )
        ),
        early_energy={"fpdeso": _early_energy(chosen_run, early), "fpd": _early_energy(fpd_run, early)},
    )


def _early_energy(run: Trajectory, samples: int) -> tuple[float, float]:
    return _pair(lambda j: control_energy(run.t_ns[:samples], run.command_torque[:samples, j]))


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
        "`python -m smm_analysis.energy_study` prints the same figures.",
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
    parser = argparse.ArgumentParser(prog="python -m smm_analysis.energy_study", description=__doc__)
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
