"""Where FPDESO's case2 torque noise comes from, and the settings that remove it (issue #15).

:func:`torque_terms` splits the torque into the law's terms; :func:`sweep_settings` runs the settings,
over the offline loop with the paper's gains. Rendering is in :mod:`smm_analysis.reproduction.energy_report`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from smm_controller.fpdeso import FPDESOConfig, FPDESOController

from smm_analysis.closed_loop import Trajectory, run_closed_loop
from smm_analysis.errors import ClosedLoopDivergedError
from smm_analysis.metrics import control_energy, rms_error, torque_increment_rms
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
    "run_energy_study",
    "run_setting",
    "sweep_settings",
    "torque_terms",
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
