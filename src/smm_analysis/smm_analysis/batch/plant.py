"""``smm_sim.plant.SimulatedPlant`` for N runs at once: saturation, D/A quantum, valve lag, RK4, stops, noise.

The same steps in the same order as the scalar plant (see its module docstring), on (N, 2) arrays with
one row per run and per-run parameters. RK4 is ``smm_dynamics``'s classical scheme on the spin form of
the model (``forward_dynamics_entries_spin_form``), written as ``rk4_step_spin_form`` writes it. Each
run's encoder noise comes from its own generator seeded with its seed, drawn for the whole run at once
(the same sequence as the scalar plant's blocks).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from smm_dynamics.integration import rk4_stages
from smm_dynamics.spin_form import forward_dynamics_entries_spin_form
from smm_sim.plant import PlantConfig, eq46_disturbance

from smm_analysis.batch.chain import BatchModel, pairs

__all__ = ["BatchPlant"]

FloatArray = NDArray[np.float64]
_NS_PER_S = 1_000_000_000


class BatchPlant:
    """N simulated plants stepped together.

    Args:
        configs: One plant configuration per run (same ``substeps`` for all).
        samples: Number of measurements the run will take (noise is drawn for that many).
    """

    def __init__(self, configs: Sequence[PlantConfig], samples: int) -> None:
        n = len(configs)
        substeps = {c.substeps for c in configs}
        if len(substeps) != 1:
            raise ValueError(f"every run of a batch needs the same substeps, got {sorted(substeps)!r}")
        self.substeps = substeps.pop()
        self.true = BatchModel([c.true_params for c in configs])
        """The true plants' parameters, as arrays of N."""
        # Rows with Coulomb friction take smm_dynamics' float path (sign(q') is not in the generated step).
        self.signed = np.any(self.true.coulomb != 0.0, axis=1)
        self.limits = pairs(configs, lambda c: c.joint_limits)
        self.saturation = pairs(configs, lambda c: c.torque_limit)
        self.quantum = pairs(configs, lambda c: c.torque_quantum)
        self.quantised = bool(np.any(self.quantum > 0.0))
        self.eq46 = np.array([c.disturbance == "eq46" for c in configs])
        self.lagged = np.array([c.valve_time_constants is not None for c in configs])
        valve = [c.valve_time_constants or (1.0, 1.0) for c in configs]
        self.rise = np.array([v[0] for v in valve])[:, None]
        self.fall = np.array([v[1] for v in valve])[:, None]
        counts = np.array([c.encoder_counts_per_rev for c in configs], dtype=np.float64)
        self.encoder_quantum = np.where(counts > 0, 2.0 * math.pi / np.where(counts > 0, counts, 1.0), 0.0)
        std = pairs(configs, lambda c: c.noise_std)
        self.noise = np.zeros((samples, n, 2))
        for row, config in enumerate(configs):
            if std[row, 0] > 0.0 or std[row, 1] > 0.0:
                normals = np.random.default_rng(config.seed).standard_normal(2 * samples).reshape(samples, 2)
                self.noise[:, row, :] = normals * std[row]
        self.state = np.zeros((n, 4))
        self.valve = np.zeros((n, 2))
        self.applied = np.zeros((n, 2))
        self.t_ns = 0
        self._sample = 0
        self.measured = self._sense()

    def _sense(self) -> FloatArray:
        measured = self.state[:, :2] + self.noise[self._sample]
        self._sample += 1
        quantum = self.encoder_quantum
        if np.any(quantum > 0.0):
            safe = np.where(quantum > 0.0, quantum, 1.0)[:, None]
            counts = measured / safe
            measured = np.where(
                quantum[:, None] > 0.0, np.copysign(np.round(counts), counts) * safe, measured
            )
        result: FloatArray = measured
        return result

    def _valve_substep(self, target: FloatArray, h: float) -> FloatArray:
        start = self.valve
        opening = (start == 0.0) | ((target > start) == (start > 0.0))
        constant = np.where(opening, self.rise, self.fall)
        decay = np.exp(-h / constant)
        self.valve = np.where(self.lagged[:, None], target + (start - target) * decay, target)
        mean = target + (start - target) * (constant / h) * (1.0 - decay)
        return np.where(self.lagged[:, None], mean, target)

    def _rk4(self, load: FloatArray, h: float) -> FloatArray:
        """One RK4 step under ``load`` = applied - disturbance torque (N m), as ``rk4_step_floats``."""
        true = self.true
        inertias, gravity = true.inertias, true.gravity
        fa, fb = true.viscous[:, 0], true.viscous[:, 1]
        ca, cb = true.coulomb[:, 0], true.coulomb[:, 1]
        oa, ob = true.offset[:, 0], true.offset[:, 1]
        signed = self.signed if np.any(self.signed) else None
        # The generated step subtracts the offset from the load, then f_v q' (and G) per stage.
        offset_a, offset_b = load[:, 0] - oa, load[:, 1] - ob

        def accel(
            a: FloatArray, b: FloatArray, ad: FloatArray, bd: FloatArray
        ) -> tuple[FloatArray, FloatArray]:
            sb = np.sin(b)
            torque_a = offset_a - ad * fa
            torque_b = offset_b - bd * fb - gravity * sb
            if signed is not None:
                # forward_dynamics_floats: load - G - (f_v q' + f_c sign(q') + offset).
                full_a = load[:, 0] - (fa * ad + ca * np.sign(ad) + oa)
                full_b = load[:, 1] - gravity * sb - (fb * bd + cb * np.sign(bd) + ob)
                torque_a = np.where(signed, full_a, torque_a)
                torque_b = np.where(signed, full_b, torque_b)
            qdd_a, qdd_b = forward_dynamics_entries_spin_form(
                np.sin(a), np.cos(a), sb, np.cos(b), ad, bd, torque_a, torque_b, *inertias
            )
            return qdd_a, qdd_b

        s = self.state
        return np.stack(rk4_stages(accel, (s[:, 0], s[:, 1], s[:, 2], s[:, 3]), h), axis=-1)

    def _stops(self, state: FloatArray) -> FloatArray:
        q, qd = state[:, :2], state[:, 2:]
        limit = self.limits
        above, below = q > limit, q < -limit
        q = np.where(above, limit, np.where(below, -limit, q))
        qd = np.where(above, np.minimum(qd, 0.0), np.where(below, np.maximum(qd, 0.0), qd))
        return np.concatenate((q, qd), axis=1)

    def step(self, command: FloatArray, dt_ns: int) -> None:
        """Applies the torque commands (N m), (N, 2), over the next dt_ns nanoseconds."""
        torque = np.clip(command, -self.saturation, self.saturation)
        if self.quantised:
            safe = np.where(self.quantum > 0.0, self.quantum, 1.0)
            torque = np.where(self.quantum > 0.0, np.round(torque / safe) * safe, torque)
        h = dt_ns / _NS_PER_S / self.substeps
        t0 = self.t_ns / _NS_PER_S
        applied = np.zeros_like(torque)
        for index in range(self.substeps):
            acting = self._valve_substep(torque, h)
            applied = applied + acting
            dist = np.array(eq46_disturbance(t0 + (index + 0.5) * h))
            load = acting - np.where(self.eq46[:, None], dist, 0.0)
            self.state = self._stops(self._rk4(load, h))
        self.applied = applied / self.substeps
        self.t_ns += dt_ns
        self.measured = self._sense()
