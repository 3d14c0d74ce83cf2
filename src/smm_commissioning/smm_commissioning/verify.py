"""``verify``: case 1 closed on the commissioned parameters, against the identified model's prediction.

The bench runs the chosen gains on the identified model through the bridge's core with the commissioned
``bridge.*``; the model's prediction is the same run on the offline loop (the sweep's plant: the identified
model with the bench's valve lag, torque limit and noise). Ready when the bench tracks within
``ready_factor`` of the prediction on both joints after the start. docs/COMMISSIONING.md, "verify".
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from smm_analysis.batch.loop import RunSettings, run_scalar
from smm_analysis.scenarios import get_scenario
from smm_analysis.sweep.spec import build_settings
from smm_controller.chain import build_chain
from smm_controller.laws import get_law
from smm_hw_bridge.bridge_config import BridgeConfig
from smm_schema.ranges import above, bounds, check_bounds

from smm_commissioning.closed import LoopRecord, run_loop
from smm_commissioning.host import BenchHost

__all__ = ["Verdict", "VerifyConfig", "predict", "run_verify", "settings_of"]


@dataclass(frozen=True)
class VerifyConfig:
    """The run ``verify`` closes and how it judges it.

    Attributes:
        duration: Case 1's length (s), in [2, 60].
        settled: Start of the compared RMS (s): case 1's first second saturates the valves, in [0, duration).
        ready_factor: The bench is ready when its RMS is at most this times the model's, per joint, >= 1.
        max_error: Largest tracking error (rad), > 0: past it the loop stops.
    """

    duration: float = field(default=5.0, metadata=bounds(2.0, 60.0))
    settled: float = field(default=1.0, metadata=bounds(0.0, 59.0))
    ready_factor: float = field(default=1.5, metadata=bounds(1.0, 100.0))
    max_error: float = field(default=0.3, metadata=above(0.0))

    def __post_init__(self) -> None:
        check_bounds(self)
        if self.settled >= self.duration:
            raise ValueError(f"settled ({self.settled}) must be below duration ({self.duration})")


@dataclass(frozen=True)
class Verdict:
    """The bench's run against the model's.

    Attributes:
        bench: Case-1 RMS on the bench after ``settled`` (alpha, beta) (rad).
        predicted: The same on the identified model (rad).
        peak: Largest |q| on the bench (rad).
        ready: Both joints within ``ready_factor`` of the prediction.
        record: The bench's run.
    """

    bench: tuple[float, float]
    predicted: tuple[float, float]
    peak: tuple[float, float]
    ready: bool
    record: LoopRecord

    @property
    def ratio(self) -> tuple[float, float]:
        """Bench over predicted RMS per joint."""
        return self.bench[0] / self.predicted[0], self.bench[1] / self.predicted[1]


def settings_of(tune: dict[str, Any], config: VerifyConfig) -> RunSettings:
    """The chosen gain set of ``tune``'s recorded spec, on case 1 of ``duration`` on the identified plant."""
    spec = tune["spec"]
    controller = {**spec["fixed"], **tune["gains"]}
    scenario = get_scenario("case1").with_duration(config.duration)
    return build_settings(spec["controller"], scenario, controller, spec["plant"], "verify")


def predict(settings: RunSettings, config: VerifyConfig) -> tuple[float, float]:
    """The model's case-1 RMS after ``settled`` (alpha, beta) (rad): the offline loop."""
    trajectory = run_scalar(settings)
    rows = trajectory.time >= config.settled - 1e-12
    error = trajectory.tracking_error[rows]
    rms = np.sqrt(np.mean(error**2, axis=0))
    return float(rms[0]), float(rms[1])


def run_verify(host: BenchHost, bridge: BridgeConfig, settings: RunSettings, config: VerifyConfig) -> Verdict:
    """Case 1 on the bench with the chosen chain; the verdict against :func:`predict`.

    Raises:
        MotionStopError, LinkLostError: As :func:`~smm_commissioning.closed.run_loop`.
    """
    law = get_law(settings.controller).build(settings.law, settings.model)
    chain = build_chain(
        settings.controller,
        settings.model,
        law=law,
        td=settings.td,
        fleso=settings.fleso,
        limiter=settings.output,
    )
    record = run_loop(
        host, bridge, chain, settings.scenario.reference(), config.duration, max_error=config.max_error
    )
    bench = record.tracking_rms(config.settled)
    predicted = predict(settings, config)
    ready = all(bench[j] <= config.ready_factor * predicted[j] for j in range(2))
    return Verdict(bench, predicted, record.peak, ready, record)
