"""The simulator's logic without ROS: stepping, stamp matching, command timeout, statistics, health, record.

Commands in (:meth:`SimCore.on_command`), ticks in (:meth:`SimCore.tick`, real time), measurements out
(:attr:`SimCore.measurement`); times are integer ns of a monotonic clock, passed in. The clock modes are
described in ``docs/LAUNCH.md`` (smm_sim_node).
"""

from __future__ import annotations

import enum
import json
import math
from collections import OrderedDict
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

import numpy as np
from smm_node_runtime.health import Health, Level, worst
from smm_node_runtime.run_verdict import VerdictConfig, late_figures, late_reason

from smm_sim.config import PlantParameters, SimNodeConfig
from smm_sim.plant import GroundTruth, Measurement, SimulatedPlant

__all__ = [
    "DEADLINE_MISS_WARN_FRACTION",
    "CommandOutcome",
    "LatencyStats",
    "PlantDivergedError",
    "RunRecorder",
    "SimCore",
    "statistics_summary",
]

_NS_PER_S: Final[int] = 1_000_000_000
DEADLINE_MISS_WARN_FRACTION: Final[float] = 0.1
"""Real time: WARN when more than this fraction of a period's ticks found the previous one unanswered."""
PUBLISHED_STAMPS_KEPT: Final[int] = 1000
"""Real time: publish times of this many recent measurements are kept to match answers (1 s at 1 kHz)."""
_REPUBLISH_SLACK: Final[float] = 0.999
"""Lockstep: a measurement is re-published once this fraction of ``republish_period`` has passed."""


class PlantDivergedError(RuntimeError):
    """The simulated plant's state became non-finite (the closed loop is unstable); the run is over."""


class CommandOutcome(enum.Enum):
    """What :meth:`SimCore.on_command` did with a valid torque command."""

    STEPPED = "stepped"
    """Lockstep: it answered the current measurement; the plant stepped."""
    ACCEPTED = "accepted"
    """Real time: it is the command in force from the next tick."""
    LATE = "late"
    """It answers a measurement already answered (a re-transmission or reordering): ignored quietly."""
    UNKNOWN_STAMP = "unknown_stamp"
    """No measurement with its stamp was published: dropped and counted."""


class LatencyStats:
    """Measurement-to-command latencies (ns), kept whole for exact percentiles (8 bytes per sample)."""

    def __init__(self) -> None:
        self._samples: list[int] = []

    def add(self, latency_ns: int) -> None:
        """Record one latency (ns)."""
        self._samples.append(latency_ns)

    @property
    def count(self) -> int:
        """Number of latencies recorded."""
        return len(self._samples)

    def percentile_us(self, percent: float) -> float:
        """The ``percent`` percentile (0-100) in microseconds; NaN when empty."""
        if not self._samples:
            return math.nan
        return float(np.percentile(np.asarray(self._samples, dtype=np.float64), percent)) / 1e3

    def summary(self) -> dict[str, float]:
        """count, p50, p90, p99 and max (us)."""
        return {
            "count": float(self.count),
            "p50_us": self.percentile_us(50.0),
            "p90_us": self.percentile_us(90.0),
            "p99_us": self.percentile_us(99.0),
            "max_us": self.percentile_us(100.0),
        }


def statistics_summary(stats: Mapping[str, Any]) -> str:
    """One log line of :meth:`SimCore.statistics`: the figures that mean something in its clock mode.

    Lockstep: steps and stepping rate (latency and deadlines do not exist: the plant waits for every
    answer). Real time: latency percentiles, deadline misses, late and zero-torque ticks. Both: the
    commands dropped.
    """
    dropped = (
        f"dropped {stats['dropped_invalid']} invalid, {stats['dropped_unknown_stamp']} unknown-stamp commands"
    )
    if stats["clock_mode"] == "lockstep":
        rate = stats["steps_per_wall_second"]
        rate_text = f" at {rate:.0f} steps/s" if math.isfinite(rate) else ""
        return f"{stats['steps']} steps{rate_text} (lockstep); republished {stats['republished']}; {dropped}"
    latency = stats["latency"]
    answers = int(latency["count"])
    latency_text = (
        f"latency p50 {latency['p50_us']:.0f} us, p99 {latency['p99_us']:.0f} us ({answers} answers)"
        if answers
        else "no command answered a measurement"
    )
    return (
        f"{stats['steps']} steps (real time); {latency_text}; deadline misses {stats['deadline_misses']}, "
        f"late ticks {stats['late_ticks']}, zero-torque ticks {stats['stale_ticks']}; {dropped}"
    )


class RunRecorder:
    """Per-step record of the run (lists of floats, converted to arrays once, by :meth:`save`)."""

    def __init__(self) -> None:
        self.stamp_ns: list[int] = []
        self.position: list[tuple[float, float]] = []
        self.velocity: list[tuple[float, float]] = []
        self.applied_torque: list[tuple[float, float]] = []
        self.measured_position: list[tuple[float, float]] = []
        self.command_stamp_ns: list[int] = []
        self.command: list[tuple[float, float]] = []

    def sample(self, truth: GroundTruth, measured: Measurement) -> None:
        """Record the state at one sample time."""
        self.stamp_ns.append(truth.stamp_ns)
        self.position.append((float(truth.position[0]), float(truth.position[1])))
        self.velocity.append((float(truth.velocity[0]), float(truth.velocity[1])))
        self.applied_torque.append((float(truth.applied_torque[0]), float(truth.applied_torque[1])))
        self.measured_position.append((float(measured.position[0]), float(measured.position[1])))

    def command_applied(self, stamp_ns: int, command: tuple[float, float]) -> None:
        """Record the command of one step and the stamp it answered (ns; -1 = none, zero torque)."""
        self.command_stamp_ns.append(stamp_ns)
        self.command.append(command)

    def save(self, path: Path) -> None:
        """Write the record as .npz (``docs/LAUNCH.md``, ``record_file``)."""
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(
            path,
            stamp_ns=np.asarray(self.stamp_ns, dtype=np.int64),
            position=np.asarray(self.position, dtype=np.float64).reshape(-1, 2),
            velocity=np.asarray(self.velocity, dtype=np.float64).reshape(-1, 2),
            applied_torque=np.asarray(self.applied_torque, dtype=np.float64).reshape(-1, 2),
            measured_position=np.asarray(self.measured_position, dtype=np.float64).reshape(-1, 2),
            command_stamp_ns=np.asarray(self.command_stamp_ns, dtype=np.int64),
            command=np.asarray(self.command, dtype=np.float64).reshape(-1, 2),
        )


class SimCore:
    """The simulated plant run in one clock mode, fed with commands and times by its node.

    Args:
        plant: The plant (fixed for the run).
        config: The run's behaviour; ``clock_mode`` and whether the run is recorded (``record_file`` set)
            are fixed here, the rest may change with :meth:`reconfigure`.
        now_ns: Monotonic time at start (ns): the first real-time tick is due one period later.
        verdict: When a real-time run counts as controlled (:meth:`run_verdict`).
    """

    def __init__(
        self, plant: PlantParameters, config: SimNodeConfig, now_ns: int, verdict: VerdictConfig | None = None
    ) -> None:
        self.plant_parameters = plant
        self.config = config
        self.verdict = verdict or VerdictConfig()
        self.clock_mode = config.clock_mode
        self.plant = SimulatedPlant(plant.plant_config)
        self.plant.reset(np.asarray(plant.initial_position))
        self.period_ns = plant.plant_config.period_ns
        self.dt = self.period_ns / _NS_PER_S
        self.step_limit = config.step_limit(self.period_ns)
        """Steps after which the run ends (None = no end)."""
        self.steps = 0
        self.dropped_invalid = 0
        self.dropped_unknown_stamp = 0
        self.ignored_late = 0
        self.republished = 0
        self.stale_ticks = 0
        """Real-time ticks that applied zero torque (no command yet, or the command in force timed out)."""
        self.command_timeouts = 0
        """Real-time ticks that applied zero torque because the command in force had timed out."""
        self.deadline_misses = 0
        self.late_ticks = 0
        self.first_live_tick: int | None = None
        """Real time: the first tick (step index) that applied a command; None while none did."""
        self.judged_ticks = 0
        """Real time: ticks from ``verdict.settle_s`` after :attr:`first_live_tick` on (judged periods)."""
        self.late_judged = 0
        """Of :attr:`judged_ticks`, those that missed their deadline or applied zero torque."""
        self.zero_torque_judged = 0
        """Of :attr:`judged_ticks`, those that applied zero torque (the command in force had timed out)."""
        self._settle_ticks = round(self.verdict.settle_s * _NS_PER_S / self.period_ns)
        self.ticks_on_stop = 0
        """Steps that ended with a joint on its mechanical stop."""
        self.published: dict[str, int] = {}
        """Messages published per topic (fully qualified name), re-publications included."""
        self.latency = LatencyStats()
        self.last_error = ""
        self.finished = False
        """True once the run reached its step limit or the plant diverged."""
        self.failure: PlantDivergedError | None = None
        """Why the run ended early (the plant diverged), None otherwise."""
        self.measurement = self.plant.measure()
        self.truth = self.plant.ground_truth
        # Kept only when asked for at start-up: a record grows by about 0.5 kB per step.
        self.recorder = RunRecorder() if config.record_file else None
        if self.recorder is not None:
            self.recorder.sample(self.truth, self.measurement)
        self._first_step_ns: int | None = None
        self._last_step_ns = 0
        self._last_publish_ns = 0
        # Real time: the command in force, the stamp it answered, when it arrived (monotonic ns).
        self._command: tuple[float, float] = (0.0, 0.0)
        self._command_stamp_ns = -1
        self._command_received_ns: int | None = None
        self._published_at: OrderedDict[int, int] = OrderedDict()
        self._answered_previous = True
        self._next_tick_ns = now_ns + self.period_ns

    @property
    def stamp_ns(self) -> int:
        """Stamp of the current measurement (ns since start)."""
        return self.plant.time_ns

    def reconfigure(self, config: SimNodeConfig) -> None:
        """Use ``config`` from now on (its ``clock_mode`` must be the running one); may end the run."""
        if config.clock_mode != self.clock_mode:
            raise ValueError(f"clock_mode is fixed at start-up ({self.clock_mode!r})")
        self.config = config
        self.step_limit = config.step_limit(self.period_ns)
        if self.step_limit is not None and self.steps >= self.step_limit:
            self.finished = True

    # ---- commands ---------------------------------------------------------------------------------

    def reject_command(self) -> int:
        """Count a command that broke the interface contract; return how many so far."""
        self.dropped_invalid += 1
        return self.dropped_invalid

    def on_command(self, stamp_ns: int, values: tuple[float, float], received_ns: int) -> CommandOutcome:
        """Take a valid torque command (N m) answering the measurement stamped ``stamp_ns``, received then."""
        if self.clock_mode == "lockstep":
            current = self.plant.time_ns
            if stamp_ns < current:
                self.ignored_late += 1
                return CommandOutcome.LATE
            if stamp_ns > current:
                self.dropped_unknown_stamp += 1
                return CommandOutcome.UNKNOWN_STAMP
            self._step(values, stamp_ns, received_ns)
            return CommandOutcome.STEPPED
        published_ns = self._published_at.get(stamp_ns)
        if published_ns is None:
            if stamp_ns <= self._command_stamp_ns or (
                self._published_at and stamp_ns < next(iter(self._published_at))
            ):
                self.ignored_late += 1
                return CommandOutcome.LATE
            self.dropped_unknown_stamp += 1
            return CommandOutcome.UNKNOWN_STAMP
        if stamp_ns <= self._command_stamp_ns:
            # Out of order or repeated: a newer answer is already in force.
            self.ignored_late += 1
            return CommandOutcome.LATE
        self._command = values
        self._command_stamp_ns = stamp_ns
        self._command_received_ns = received_ns
        self.latency.add(received_ns - published_ns)
        if stamp_ns == self.plant.time_ns:
            self._answered_previous = True
        return CommandOutcome.ACCEPTED

    # ---- time -------------------------------------------------------------------------------------

    def tick(self, now_ns: int) -> int | None:
        """Real time: one timer tick at ``now_ns``: step with the command in force, or zero torque.

        Returns:
            The age (ns) of the command in force when it timed out at this tick (zero torque applied),
            else None.
        """
        if now_ns - self._next_tick_ns > self.period_ns:
            self.late_ticks += 1
        self._next_tick_ns = max(self._next_tick_ns + self.period_ns, now_ns)
        missed = not self._answered_previous
        if missed:
            self.deadline_misses += 1
        received = self._command_received_ns
        timed_out: int | None = None
        stale = received is None or now_ns - received > self.config.command_timeout * _NS_PER_S
        if stale:
            command, stamp_ns = (0.0, 0.0), -1
            self.stale_ticks += 1
            if received is not None:
                self.command_timeouts += 1
                self.last_error = f"command timed out (> {self.config.command_timeout:g} s): zero torque"
                timed_out = now_ns - received
        else:
            command, stamp_ns = self._command, self._command_stamp_ns
        self._judge(missed=missed, zero_torque=stale)
        self._step(command, stamp_ns, now_ns)
        if not self.finished:
            self._answered_previous = False
        return timed_out

    def _judge(self, *, missed: bool, zero_torque: bool) -> None:
        """Count the tick about to step for the verdict (docs/LAUNCH.md, "Shutdown and exit codes")."""
        if self.first_live_tick is None:
            if zero_torque:
                return  # not live yet: no command has arrived
            self.first_live_tick = self.steps
        if self.steps - self.first_live_tick < self._settle_ticks:
            return
        self.judged_ticks += 1
        if missed or zero_torque:
            self.late_judged += 1
        if zero_torque:
            self.zero_torque_judged += 1

    def run_verdict(self) -> str | None:
        """Real time: why the run did not control, or None if it did (always None in lockstep).

        It did not control when no command ever reached the plant, when a tick after the settling time
        applied zero torque (the command in force had timed out), or when more than ``verdict.late_limit``
        of the ticks after the settling time missed their deadline or applied zero torque.
        """
        if self.clock_mode != "realtime":
            return None
        if self.first_live_tick is None:
            return f"no torque command reached the plant: all {self.steps} ticks applied zero torque"
        reasons = []
        if self.zero_torque_judged:
            reasons.append(
                f"{self.zero_torque_judged} ticks after the first {self.verdict.settle_s:g} s live applied "
                f"zero torque (no valid command within command_timeout "
                f"{self.config.command_timeout * 1e3:g} ms)"
            )
        late = late_reason(self.late_judged, self.judged_ticks, self.verdict)
        if late is not None:
            reasons.append(late)
        return "; ".join(reasons) or None

    def verdict_figures(self) -> str:
        """``late L of N periods of T ms after the first S s live (P %), Z zero-torque ticks before live``."""
        late = late_figures(self.late_judged, self.judged_ticks, self.dt * 1e3, self.verdict)
        before = self.first_live_tick if self.first_live_tick is not None else self.steps
        return f"{late}, {before} zero-torque ticks before the first command (not judged)"

    def sent(self, now_ns: int) -> None:
        """The current measurement was published at ``now_ns``."""
        self._last_publish_ns = now_ns
        if self.clock_mode == "realtime":
            self._published_at[self.plant.time_ns] = now_ns
            while len(self._published_at) > PUBLISHED_STAMPS_KEPT:
                self._published_at.popitem(last=False)

    def count_published(self, topic: str) -> None:
        """Count one message published on ``topic``."""
        self.published[topic] = self.published.get(topic, 0) + 1

    def republish_due(self, now_ns: int) -> bool:
        """Lockstep: True (and counted) when the unanswered measurement is due to be published again."""
        if self.finished or now_ns - self._last_publish_ns < self.config.republish_period * _NS_PER_S * (
            _REPUBLISH_SLACK
        ):
            return False
        self.republished += 1
        return True

    def _step(self, command: tuple[float, float], command_stamp_ns: int, now_ns: int) -> None:
        self.plant.step(command, self.dt)
        self.steps += 1
        self._last_step_ns = now_ns
        if self._first_step_ns is None:
            self._first_step_ns = now_ns
        self.measurement = self.plant.measure()
        self.truth = self.plant.ground_truth
        if self.recorder is not None:
            self.recorder.command_applied(command_stamp_ns, command)
            self.recorder.sample(self.truth, self.measurement)
        position = self.truth.position
        limits = self.plant_parameters.joint_limits
        if abs(position[0]) >= limits[0] or abs(position[1]) >= limits[1]:
            self.ticks_on_stop += 1
        state = (*self.truth.position.tolist(), *self.truth.velocity.tolist())
        if not all(map(math.isfinite, state)):
            self.finished = True
            self.failure = PlantDivergedError(
                f"plant state became non-finite at t = {self.plant.time_ns / _NS_PER_S:g} s after torque "
                f"{list(command)} N m (unstable closed loop?); stopping the simulation"
            )
        if self.step_limit is not None and self.steps >= self.step_limit:
            self.finished = True

    # ---- figures ----------------------------------------------------------------------------------

    def statistics(self) -> dict[str, Any]:
        """Counters, latency figures and stepping rate of the run so far (JSON-serialisable).

        ``steps_per_wall_second`` counts from the first step to the last, so start-up and discovery are
        not in it.
        """
        first = self._first_step_ns
        stepping_s = 0.0 if first is None else (self._last_step_ns - first) / _NS_PER_S
        return {
            "clock_mode": self.clock_mode,
            "steps": self.steps,
            "control_period_s": self.dt,
            "dropped_invalid": self.dropped_invalid,
            "dropped_unknown_stamp": self.dropped_unknown_stamp,
            "ignored_late": self.ignored_late,
            "republished": self.republished,
            "published": dict(sorted(self.published.items())),
            "stale_ticks": self.stale_ticks,
            "deadline_misses": self.deadline_misses,
            "late_ticks": self.late_ticks,
            "judged_ticks": self.judged_ticks,
            "late_judged": self.late_judged,
            "zero_torque_judged": self.zero_torque_judged,
            "verdict": self.run_verdict(),
            "latency": self.latency.summary(),
            "stepping_wall_s": stepping_s,
            "steps_per_wall_second": (self.steps - 1) / stepping_s if stepping_s > 0.0 else math.nan,
        }

    def health_counts(self) -> dict[str, int]:
        """Counts judged per diagnostics period (``docs/NODES.md``, smm_sim_node status)."""
        return {
            "steps": self.steps,
            "dropped_invalid": self.dropped_invalid,
            "dropped_unknown_stamp": self.dropped_unknown_stamp,
            "command_timeouts": self.command_timeouts,
            "deadline_misses": self.deadline_misses,
            "late_ticks": self.late_ticks,
            "ticks_on_stop": self.ticks_on_stop,
            "republished": self.republished,
        }

    def health(self, last: Mapping[str, int], current: Mapping[str, int], steps_per_s: float) -> Health:
        """OK / WARN / ERROR by the thresholds of ``docs/NODES.md``.

        Args:
            last: Increase of each :meth:`health_counts` count over the last complete diagnostics period.
            current: Increase since the current period started.
            steps_per_s: Stepping rate over the last complete period (1/s).
        """

        def recent(name: str) -> int:
            return last.get(name, 0) + current.get(name, 0)

        findings: list[tuple[Level, str]] = []
        if self.failure is not None:
            findings.append((Level.ERROR, "the plant diverged"))
        if recent("command_timeouts"):
            findings.append((Level.ERROR, "no valid command in time: zero torque applied"))
        for name in ("dropped_invalid", "dropped_unknown_stamp", "ticks_on_stop", "late_ticks"):
            if recent(name):
                findings.append((Level.WARN, f"{name}: {recent(name)} in the last period"))
        steps = last.get("steps", 0)
        if steps and last.get("deadline_misses", 0) > DEADLINE_MISS_WARN_FRACTION * steps:
            findings.append(
                (Level.WARN, f"{last['deadline_misses']} of {steps} ticks found no answer in time")
            )
        values: dict[str, object] = {
            "loop_rate_hz": f"{steps_per_s:.1f}",
            "clock_mode": self.clock_mode,
            **self.health_counts(),
            "last_error": self.last_error,
        }
        return worst(findings, "stepping" if self.steps else "waiting for the first command", values)

    def write_outputs(self) -> None:
        """Write ``record_file`` and ``stats_file`` (when set) with the run so far."""
        config = self.config
        if config.record_file and self.recorder is not None:
            self.recorder.save(Path(config.record_file))
        if config.stats_file:
            path = Path(config.stats_file)
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(self.statistics(), indent=2, allow_nan=True))
