"""The preflight: before arming, rehearse the loop with output disabled and judge whether this host holds it.

The bridge records, per control period of the rehearsal, when the feedback frame arrived and when the answer
was ready (:class:`RehearsalRecorder`); :func:`judge` turns the figures into a verdict: hold, or refuse with
the fastest candidate rate predicted to hold. Why and how the prediction is made: docs/LAUNCH.md, "Preflight".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Final

import numpy as np
from smm_schema.ranges import bounds, check_bounds

from smm_hw_bridge.control_rate import BOARD_TICK_HZ, CONTROL_RATES_HZ
from smm_hw_bridge.idle_states import IdleStates, read_idle_states

__all__ = [
    "CANDIDATE_DIVIDERS",
    "EXIT_PREFLIGHT_REFUSED",
    "WARM_UP_S",
    "PreflightConfig",
    "PreflightVerdict",
    "RehearsalFigures",
    "RehearsalRecorder",
    "judge",
]

EXIT_PREFLIGHT_REFUSED: Final[int] = 4
"""Exit code of a hardware run whose preflight refused to arm (the host cannot hold the control rate)."""
CANDIDATE_DIVIDERS: Final[tuple[int, ...]] = tuple(BOARD_TICK_HZ // rate for rate in CONTROL_RATES_HZ)
"""Board ticks per control period of the rates the preflight names (1000 ... 100 Hz: 1, 2, 4, 5, 10)."""
WARM_UP_S: Final[float] = 0.25
"""The rehearsal's first seconds are not judged (first steps of the chain, caches, the DDS discovery)."""


@dataclass(frozen=True)
class PreflightConfig:
    """The preflight's settings (``hw_bridge_node`` parameters ``preflight.*``).

    Attributes:
        duration_s: How long the loop is rehearsed with output disabled before arming (s), in [0, 30];
            0 skips the preflight. Never in lockstep.
        force: Arm even when the preflight finds the rate is not held (with a warning).
        added_latency_us: Added to every rehearsed feedback -> command time (us), in [0, 1e6]: rehearses a
            slower host (tests, what-if); 0 on the bench.
        unseen_late: The late share a short rehearsal does not see (fraction, in [0, 1]), added to every
            prediction: the host's stalls come in bursts a 3 s sample often misses (the run was late by
            0.30 points more than the rehearsal in the median of 35 runs here; docs/LAUNCH.md, "Measured:
            the rehearsal's prediction"). A rate holds when its prediction is within the late limit.
    """

    duration_s: float = field(default=3.0, metadata=bounds(0.0, 30.0))
    force: bool = False
    added_latency_us: float = field(default=0.0, metadata=bounds(0.0, 1e6))
    unseen_late: float = field(default=0.0035, metadata=bounds(0.0, 1.0))

    def __post_init__(self) -> None:
        check_bounds(self)
        if not isinstance(self.force, bool):
            raise ValueError(f"force must be a bool, got {self.force!r}")


@dataclass(frozen=True)
class RehearsalFigures:
    """What a rehearsal measured, per control period after the warm-up.

    Attributes:
        board_period_ns: The board's tick (ns).
        divider: Board ticks per control period of the rehearsal.
        feedback_to_command_us: Per answered control period: the answer ready after the board's tick (us),
            the tick's time taken from the arrivals' lower envelope (so without the frame's way there).
        wakeup_us: Per feedback frame: its arrival after that tick (us).
        unanswered: Control periods without an answer (frame lost, refused, or no command came).
        idle_states: The CPUs' idle-state setting during the rehearsal; None when not known.
    """

    board_period_ns: int
    divider: int
    feedback_to_command_us: tuple[float, ...]
    wakeup_us: tuple[float, ...]
    unanswered: int = 0
    idle_states: IdleStates | None = None

    @property
    def periods(self) -> int:
        """Control periods judged (answered and unanswered)."""
        return len(self.feedback_to_command_us) + self.unanswered

    @property
    def rate_hz(self) -> float:
        """The rehearsed control rate (Hz)."""
        return 1e9 / (self.board_period_ns * self.divider)

    def late_share(self, divider: int) -> float:
        """Share of control periods answered after ``divider`` board ticks or not at all."""
        if not self.periods:
            return 1.0
        budget_us = divider * self.board_period_ns / 1e3
        late = int(np.count_nonzero(np.asarray(self.feedback_to_command_us) > budget_us))
        return (late + self.unanswered) / self.periods


def _percentiles(values: tuple[float, ...]) -> str:
    if not values:
        return "none measured"
    data = np.asarray(values)
    p50, p99 = np.percentile(data, (50, 99), method="inverted_cdf")
    return f"p50 {p50:.0f} us, p99 {p99:.0f} us, max {data.max():.0f} us over {data.size}"


@dataclass(frozen=True)
class PreflightVerdict:
    """The preflight's judgement of one rehearsal.

    Attributes:
        figures: The rehearsal.
        late_limit: Largest late share the run may have (fraction).
        unseen_late: Added to each rehearsed share to predict the run's (:class:`PreflightConfig`).
        predicted: Candidate rate (Hz) -> predicted late share of the run, fastest first.
        fastest_held_hz: The fastest candidate predicted within the limit; None if none is.
    """

    figures: RehearsalFigures
    late_limit: float
    unseen_late: float
    predicted: tuple[tuple[float, float], ...]
    fastest_held_hz: float | None

    @property
    def late_share(self) -> float:
        """Late share of the rehearsal at its own rate."""
        return self.figures.late_share(self.figures.divider)

    @property
    def prediction(self) -> float:
        """The run's predicted late share at the rehearsed rate."""
        return min(1.0, self.late_share + self.unseen_late)

    @property
    def holds(self) -> bool:
        """True when the rehearsed rate is predicted within the limit."""
        return self.prediction <= self.late_limit

    def lines(self) -> list[str]:
        """The figures block, one statement per line."""
        figures = self.figures
        predicted = " / ".join(f"{100.0 * share:.2f} % at {rate:g} Hz" for rate, share in self.predicted)
        idle = figures.idle_states
        return [
            f"rehearsed the loop with output disabled (safe frames) at {figures.rate_hz:g} Hz control "
            f"({figures.divider} board tick(s) of {figures.board_period_ns / 1e6:g} ms per period): "
            f"{figures.periods} control periods after the first {WARM_UP_S:g} s",
            f"feedback->command (from the board's tick, the host's estimate): "
            f"{_percentiles(figures.feedback_to_command_us)}",
            f"wake-up (feedback frame arrival after the board's tick): {_percentiles(figures.wakeup_us)}",
            *([] if idle is None else [f"idle states: {idle.statement()}"]),
            f"late {100.0 * self.late_share:.2f} % of control periods "
            f"({figures.unanswered} unanswered); the run, with {100.0 * self.unseen_late:g} points a short "
            f"rehearsal does not see (preflight.unseen_late), limit {100.0 * self.late_limit:g} %, "
            f"predicted: {predicted}",
        ]

    def refusal(self, *, direct_loop: bool, realtime: bool) -> str:
        """Why the run may not arm, what rate it holds, and the other options (for a refused verdict).

        Args:
            direct_loop: The host is the direct loop already (not named as an option then).
            realtime: The host runs under a real-time policy already (not named then).
        """
        rate = self.figures.rate_hz
        held = (
            f"the fastest candidate rate it holds is {self.fastest_held_hz:g} Hz "
            f"(--control-rate {self.fastest_held_hz:g})"
            if self.fastest_held_hz is not None
            else "none of the candidate rates holds ("
            + ", ".join(f"{r:g}" for r, _ in self.predicted)
            + " Hz)"
        )
        idle = self.figures.idle_states
        options = [] if realtime else ["real-time priority (--rt-priority N; needs an rtprio limit)"]
        if idle is not None and not idle.held:
            options.append(
                "CPUs kept out of deep idle states (/dev/cpu_dma_latency held at 0: docs/LAUNCH.md)"
            )
        options.append("an isolated core (isolcpus, taskset)")
        if not direct_loop:
            options.append("the direct loop (--loop direct)")
        return (
            f"this host does not hold {rate:g} Hz control: {100.0 * self.late_share:.2f} % of the rehearsed "
            f"control periods were late, so the run is predicted {100.0 * self.prediction:.2f} % late "
            f"(with {100.0 * self.unseen_late:g} points a short rehearsal does not see), above the limit of "
            f"{100.0 * self.late_limit:g} %; {held}; other "
            f"options: {', '.join(options)}; --force arms anyway"
        )


def judge(
    figures: RehearsalFigures,
    late_limit: float,
    dividers: tuple[int, ...] = CANDIDATE_DIVIDERS,
    unseen_late: float = 0.0,
) -> PreflightVerdict:
    """Judges a rehearsal: the run's predicted late share per candidate rate, the fastest within the limit.

    The prediction for a candidate rate counts the rehearsed answers slower than its control period, plus
    ``unseen_late``; it assumes the time per answer does not depend on the rate: for a slower rate than the
    rehearsed one it errs on the safe side (fewer steps per second load the host less); for a faster one it
    is optimistic.

    Raises:
        ValueError: ``late_limit`` or ``unseen_late`` not in [0, 1], or a divider < 1.
    """
    for name, share in (("late_limit", late_limit), ("unseen_late", unseen_late)):
        if not 0.0 <= share <= 1.0 or not math.isfinite(share):
            raise ValueError(f"{name} must be a fraction in [0, 1], got {share!r}")
    if any(d < 1 for d in dividers):
        raise ValueError(f"dividers must be >= 1, got {dividers!r}")
    predicted = tuple(
        (1e9 / (figures.board_period_ns * d), min(1.0, figures.late_share(d) + unseen_late))
        for d in sorted(set(dividers))
    )
    held = [rate for rate, share in predicted if share <= late_limit]
    return PreflightVerdict(figures, late_limit, unseen_late, predicted, max(held) if held else None)


class RehearsalRecorder:
    """Collects a rehearsal's arrivals and answers by board tick (times from ``time.monotonic_ns``).

    Args:
        board_period_ns: The board's tick (ns), > 0.
        divider: Board ticks per control period (the chain answers one tick in so many), >= 1.
        added_latency_us: Added to every answer's time (us), >= 0 (:class:`PreflightConfig`).
        idle_states: The CPUs' idle-state setting to report; None: read now (:func:`read_idle_states`).
        every: Board ticks between two feedbacks: 1 (a board), N (a CANopen SYNC a control period).
    """

    def __init__(
        self,
        board_period_ns: int,
        divider: int = 1,
        added_latency_us: float = 0.0,
        idle_states: IdleStates | None = None,
        every: int = 1,
    ) -> None:
        if board_period_ns <= 0 or divider < 1 or added_latency_us < 0.0:
            raise ValueError(
                f"need board_period_ns > 0, divider >= 1, added_latency_us >= 0, got {board_period_ns!r}, "
                f"{divider!r}, {added_latency_us!r}"
            )
        self.board_period_ns = board_period_ns
        self.divider = divider
        self.every = every
        self.added_ns = round(added_latency_us * 1e3)
        self.idle_states = read_idle_states() if idle_states is None else idle_states
        self._arrivals: dict[int, int] = {}
        self._control: set[int] = set()
        self._answers: dict[int, int] = {}

    def on_feedback(self, tick: int, rx_ns: int, control: bool) -> None:
        """The frame of board tick ``tick`` (unwrapped) arrived at ``rx_ns`` (ns); the first one counts.

        ``control``: a control tick, one the chain answers.
        """
        if tick not in self._arrivals:
            self._arrivals[tick] = rx_ns
            if control:
                self._control.add(tick)

    def on_answer(self, tick: int, ready_ns: int) -> None:
        """The answer to tick ``tick`` was ready to send at ``ready_ns`` (the first answer counts)."""
        if tick in self._control:
            self._answers.setdefault(tick, ready_ns + self.added_ns)

    def figures(self) -> RehearsalFigures:
        """The figures after the warm-up: the ticks' times from the arrivals' lower envelope.

        Control periods whose frame never came (lost, or not read) count as unanswered: the ticks missing
        between the first and the last judged one, divided by the divider.
        """
        period = self.board_period_ns
        ticks = np.array(sorted(self._arrivals), dtype=np.int64)
        if ticks.size == 0:
            return RehearsalFigures(period, self.divider, (), (), 0, self.idle_states)
        arrivals = np.array([self._arrivals[t] for t in ticks], dtype=np.int64)
        grid = tick_grid(ticks, arrivals, period)
        judged = ticks >= ticks[0] + round(WARM_UP_S * 1e9 / period)
        latencies: list[float] = []
        unanswered = 0
        for tick, at in zip(ticks[judged].tolist(), grid[judged].tolist(), strict=True):
            if tick not in self._control:
                continue
            if tick in self._answers:
                latencies.append((self._answers[tick] - at) / 1e3)
            else:
                unanswered += 1
        if judged.any():
            kept = ticks[judged]
            missing = int(kept[-1] - kept[0]) // self.every + 1 - kept.size  # feedbacks never seen
            unanswered += missing * self.every // self.divider
        wakeups = ((arrivals[judged] - grid[judged]) / 1e3).tolist()
        return RehearsalFigures(
            period, self.divider, tuple(latencies), tuple(wakeups), unanswered, self.idle_states
        )


def tick_grid(ticks: np.ndarray, arrivals_ns: np.ndarray, period_ns: int) -> np.ndarray:
    """The board's tick times (ns) on the host's clock: the lower envelope of the arrivals.

    A line through the earliest arrival (after its tick) of each half of the rehearsal, lowered to the
    earliest of all: allows for a board clock that drifts against the host's (ppm over seconds).
    """
    offsets = arrivals_ns - ticks * period_ns
    half = max(1, ticks.size // 2)
    a = int(np.argmin(offsets[:half]))
    b = half + int(np.argmin(offsets[half:])) if ticks.size > half else a
    slope = 0.0 if ticks[b] == ticks[a] else (offsets[b] - offsets[a]) / float(ticks[b] - ticks[a])
    line = offsets[a] + slope * (ticks - ticks[a]).astype(np.float64)
    line += float(np.min(offsets - line))
    result: np.ndarray = ticks * period_ns + np.round(line).astype(np.int64)
    return result
