"""Emulated benches drawn away from the defaults (issue 45's acceptance ranges), seeded, as bench files;
the in-process lockstep bench with a broken sensor."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from smm_bench_emulator.bench_file import bench_from_document, default_bench
from smm_bench_emulator.board import BoardConfig
from smm_commissioning.emulated import LockstepDevice
from smm_commissioning.identify import LOOP_BLEND, OPEN_MARGIN
from smm_hw_bridge.core import BridgeConfig
from smm_hw_bridge.device import Reading
from smm_hw_bridge.protocol import CODE_MAX, FeedbackFrame
from smm_schema.fields import config_from_parameters

NOISE_STD = 2e-5
"""Position noise of the drawn benches' encoders (rad, about 3 counts): a live encoder jitters at rest."""


def draw_document(seed: int, **overrides: Any) -> dict[str, Any]:
    """A bench description: gains per direction 0.7-1.3, overlap 200-1500 codes, null bias within +-300
    codes, one valve reversed, one encoder counting down, random zero offsets, inertias and lever +-20 %."""
    rng = np.random.default_rng(seed)
    params = default_bench().plant.params
    scale = lambda: float(rng.uniform(0.8, 1.2))  # noqa: E731
    reversed_valve = int(rng.integers(2))
    down_encoder = int(rng.integers(2))
    document: dict[str, Any] = {
        "plant": {
            "params": {
                "I11": params.I11 * scale(),
                "I22": params.I22 * scale(),
                "I44": params.I44 * scale(),
                "mass_lever": params.mass_lever * scale(),
            },
            "noise_std": [NOISE_STD, NOISE_STD],
            "seed": seed,
        },
        "valve_gain_positive": [float(g) for g in rng.uniform(0.7, 1.3, 2)],
        "valve_gain_negative": [float(g) for g in rng.uniform(0.7, 1.3, 2)],
        "valve_deadband": [float(d) for d in rng.uniform(200.0, 1500.0, 2)],
        "valve_null_bias": [float(b) for b in rng.uniform(-300.0, 300.0, 2)],
        "valve_polarity": [-1 if j == reversed_valve else 1 for j in range(2)],
        "direction": [-1 if j == down_encoder else 1 for j in range(2)],
        "zero_offset": [int(z) for z in rng.integers(0, 1 << 32, 2)],
        "seed": seed,
    }
    document.update(overrides)
    return document


def draw_bench(seed: int, **overrides: Any) -> BoardConfig:
    """The bench of :func:`draw_document`."""
    return bench_from_document(draw_document(seed, **overrides))


def write_bench(path: Path, seed: int, **overrides: Any) -> Path:
    """Writes :func:`draw_document` as a bench file; returns ``path``."""
    path.write_text(yaml.safe_dump(draw_document(seed, **overrides)), encoding="utf-8")
    return path


class FaultyDevice(LockstepDevice):
    """Feedback with joint ``frozen_encoder``'s counter frozen at its first value, and/or A/D channel
    ``stuck_channel`` at ``stuck_code``."""

    def __init__(
        self,
        config: BoardConfig,
        frozen_encoder: int | None = None,
        stuck_channel: int | None = None,
        stuck_code: int = 2048,
    ) -> None:
        super().__init__(config)
        self.frozen_encoder = frozen_encoder
        self.stuck_channel = stuck_channel
        self.stuck_code = stuck_code
        self._frozen: int | None = None

    def read(self, timeout_s: float) -> Reading | None:
        reading = super().read(timeout_s)
        if not isinstance(reading, FeedbackFrame):
            return reading
        if self.frozen_encoder is not None:
            counts = list(reading.counts)
            if self._frozen is None:
                self._frozen = counts[self.frozen_encoder]
            counts[self.frozen_encoder] = self._frozen
            reading = dataclasses.replace(reading, counts=(counts[0], counts[1]))
        if self.stuck_channel is not None:
            adc = list(reading.adc)
            adc[self.stuck_channel] = self.stuck_code
            reading = dataclasses.replace(reading, adc=(adc[0], adc[1], adc[2], adc[3]))
        return reading


def truth_parameters(bench: BoardConfig) -> dict[str, object]:
    """The bridge parameters that carry the bench's own truths, with identify's compensation settings."""
    nominal = [CODE_MAX / bench.full_scale_torque[j] for j in range(2)]
    return {
        "bridge.encoder.direction": list(bench.direction),
        "bridge.encoder.zero_offset": list(bench.zero_offset),
        "bridge.valve.polarity": list(bench.valve_polarity),
        "bridge.valve.null_bias": list(bench.valve_null_bias),
        "bridge.valve.deadband": [d + OPEN_MARGIN for d in bench.valve_deadband],
        "bridge.valve.gain": [nominal[j] / bench.valve_gain_positive[j] for j in range(2)],
        "bridge.valve.gain_negative": [nominal[j] / bench.valve_gain_negative[j] for j in range(2)],
        "bridge.valve.deadband_blend": LOOP_BLEND,
    }


def bridge_of(parameters: Mapping[str, object]) -> BridgeConfig:
    """The lockstep bridge's config of ``bridge.*`` parameters."""
    return config_from_parameters(BridgeConfig, BridgeConfig(lockstep=True), parameters, prefix="bridge")
