"""PNG figures of recorded runs, several runs overlaid, drawn from per-column min/max envelopes.

Tracking, error, torque, estimated vs true disturbance, observer bandwidth, fuzzy gains (one panel per
joint); the loop latency's distribution (one panel, p50 and p99 marked). Every series is collected block by
block into an :class:`~smm_analysis.runs.envelope.Envelope` (bounded memory, no spike lost) and the latency
into a :class:`~smm_analysis.runs.latency.LatencySketch`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from contextlib import AbstractContextManager
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray
from smm_bag.manifest import RunManifest
from smm_sim.plant import disturbance_torque

from smm_analysis.lumped import recorded_lumped_disturbance
from smm_analysis.runs.envelope import Envelope
from smm_analysis.runs.latency import LatencySketch
from smm_analysis.runs.stream import JOINTS, StepBlock
from smm_analysis.scenarios import get_scenario

__all__ = ["PLOTS", "RunFigures", "drawing", "true_disturbance", "write_plots"]

FloatArray = NDArray[np.float64]
_DPI = 80

PLOTS = ("tracking", "error", "torque", "disturbance", "bandwidth", "fuzzy_gains", "latency")
"""Figure names (``<name>.png``)."""
_PANELS = {
    "tracking": ("tracking", "rad"),
    "error": ("tracking error q_d - q", "rad"),
    "torque": ("torque", "N m"),
    "disturbance": ("disturbance", "N m"),
    "bandwidth": ("observer bandwidth", "rad/s"),
    "fuzzy_gains": ("fuzzy gains", "gain"),
}


def drawing() -> AbstractContextManager[None]:
    """Matplotlib settings for envelope figures: Agg draws long paths in chunks of 200 vertices.

    An hour's envelope is a zig-zag of full-height segments; drawn as one path, Agg's rasterizer held
    memory in proportion to the area it covers (about 15 MiB a figure, not given back: 284 MiB peak for a
    60-minute ``analyze``, 194 without figures).
    """
    return matplotlib.rc_context({"agg.path.chunksize": 200})


def true_disturbance(manifest: RunManifest, time_s: FloatArray) -> FloatArray | None:
    """The scenario's disturbance model at ``time_s`` (s since the first step), (N m), shape (N, 2).

    Simulator runs only: the manifest names the scenario, whose model gives the torque the plant applied;
    None when unknown.
    """
    if manifest.plant != "sim" or not manifest.scenario:
        return None
    try:
        model = get_scenario(manifest.scenario).disturbance
    except ValueError:  # a scenario this version does not know
        return None
    return np.array([disturbance_torque(model, float(t)) for t in time_s]).reshape(-1, 2)


class _LumpedStream:
    """The true lumped disturbance block by block, one block late, with one step of context on both sides.

    Each block's values equal those of :func:`recorded_lumped_disturbance` on the whole run.
    """

    def __init__(self, parameters: Mapping[str, Mapping[str, object]]) -> None:
        self.parameters = parameters
        self.held: tuple[FloatArray, FloatArray, FloatArray] | None = None
        self.before: tuple[FloatArray, FloatArray, FloatArray] | None = None

    def add(
        self, t_s: FloatArray, position: FloatArray, applied: FloatArray
    ) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        """Feeds a block; returns the previous block's times and series, if any."""
        current = (t_s, position, applied)
        out = None if self.held is None else self._compute(self.held, current)
        self.before, self.held = self.held, current
        return out

    def finish(self) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        """The last block's times and series."""
        return None if self.held is None else self._compute(self.held, None)

    def _compute(
        self,
        held: tuple[FloatArray, FloatArray, FloatArray],
        after: tuple[FloatArray, FloatArray, FloatArray] | None,
    ) -> tuple[FloatArray, dict[str, FloatArray]] | None:
        pieces = [held]
        lead = 0
        if self.before is not None:
            pieces.insert(0, tuple(a[-1:] for a in self.before))  # type: ignore[arg-type]
            lead = 1
        if after is not None:
            pieces.append(tuple(a[:1] for a in after))  # type: ignore[arg-type]
        t_s, position, applied = (np.concatenate([p[i] for p in pieces]) for i in range(3))
        parts = recorded_lumped_disturbance(self.parameters, t_s, position, applied)
        if parts is None:
            return None
        middle = slice(lead, lead + held[0].size)
        return held[0], {"total": parts.total[middle], "model_error": parts.model_error[middle]}


class RunFigures:
    """The figures' series of one run, collected block by block.

    Args:
        label: The run's name in legends.
        manifest: Its manifest (scenario, plant, parameters for the true disturbances).
        position_source: ``"ground truth"`` or ``"measured"``.
    """

    def __init__(self, label: str, manifest: RunManifest, position_source: str) -> None:
        self.label = label
        self.manifest = manifest
        self.position_source = position_source
        self.envelope = Envelope()
        self.lumped_envelope = Envelope()
        """The true lumped disturbance (one block behind ``envelope``, on its own columns)."""
        self.latency = LatencySketch()
        self.styles: dict[str, tuple[str, str, str]] = {}
        """series key -> (figure, legend label, line style)."""
        self.t0: int | None = None
        self.lumped = (
            _LumpedStream(manifest.parameters)
            if manifest.plant == "sim" and position_source == "ground truth"
            else None
        )

    def _series(
        self, figure: str, name: str, style: str, values: FloatArray, out: dict[str, FloatArray]
    ) -> None:
        for j in range(2):
            key = f"{figure}|{name}|{j}"
            self.styles.setdefault(key, (figure, f"{self.label} {name}".strip(), style))
            out[key] = np.ascontiguousarray(values[:, j], dtype=np.float64)

    def add(self, block: StepBlock) -> None:
        """Adds the next steps of the run."""
        if block.t_ns.size == 0:
            return
        if self.t0 is None:
            self.t0 = int(block.t_ns[0])
        t_s = (block.t_ns - self.t0).astype(np.float64) / 1e9
        self.latency.add(block.latency_ns)
        series: dict[str, FloatArray] = {}
        desired = block.desired_position
        self._series("tracking", "q_d", "--", desired, series)
        self._series("tracking", f"q ({self.position_source})", "-", block.position, series)
        self._series("error", "", "-", desired - block.position, series)
        self._series("torque", "command", "-", block.command_torque, series)
        if np.any(np.isfinite(block.applied_torque)):
            self._series("torque", "applied (prev. interval)", ":", block.applied_torque, series)
        if np.any(np.isfinite(block.disturbance_estimate)):
            self._series("disturbance", "estimate xi~", "-", block.disturbance_estimate, series)
        truth = true_disturbance(self.manifest, t_s)
        if truth is not None:
            self._series(
                "disturbance", f"true external (scenario {self.manifest.scenario})", "--", truth, series
            )
        for key, values in sorted(block.internals.items()):
            if key.endswith("bandwidth"):
                self._series("bandwidth", key, "-", values, series)
            elif key.endswith((".kp", ".kd")):
                self._series("fuzzy_gains", key, "-", values, series)
        self.envelope.add(t_s, series)
        if self.lumped is not None and np.all(np.isfinite(block.applied_torque)):
            self._add_lumped(self.lumped.add(t_s, block.position, block.applied_torque))

    def _add_lumped(self, computed: tuple[FloatArray, dict[str, FloatArray]] | None) -> None:
        if computed is None:
            return
        t_s, parts = computed
        series: dict[str, FloatArray] = {}
        self._series("disturbance", "true lumped (model error + external)", "-.", parts["total"], series)
        self._series("disturbance", "model-error part", ":", parts["model_error"], series)
        self.lumped_envelope.add(t_s, series)

    def finish(self) -> None:
        """Flushes what is held back (the last block of the lumped disturbance)."""
        if self.lumped is not None:
            self._add_lumped(self.lumped.finish())
            self.lumped = None

    def lines(self, figure: str, joint: int) -> list[tuple[str, str, FloatArray, FloatArray]]:
        """(legend label, style, x, y) of the figure's envelope lines for one joint."""
        result = []
        for envelope in (self.envelope, self.lumped_envelope):
            for key in envelope.names():
                kind, label, style = self.styles[key]
                if kind != figure or not key.endswith(f"|{joint}") or not envelope.drawn(key):
                    continue
                x, y = envelope.line(key)
                result.append((label, style, x, y))
        return result


def _figure(runs: Sequence[RunFigures], name: str) -> Figure | None:
    title, unit = _PANELS[name]
    figure, axes = plt.subplots(1, 2, figsize=(10.0, 3.6), sharex=True)
    drawn = False
    for index, joint in enumerate(JOINTS):
        axis = axes[index]
        for run in runs:
            for label, style, x, y in run.lines(name, index):
                axis.plot(x, y, style, label=label, linewidth=0.9)
                drawn = True
        axis.set_title(f"{title}: {joint}")
        axis.set_xlabel("t (s)")
        axis.set_ylabel(unit)
        axis.grid(True, alpha=0.3)
        if axis.lines:
            axis.legend(fontsize=7)
    figure.tight_layout()
    if not drawn:
        plt.close(figure)
        return None
    return figure


def _latency_figure(runs: Sequence[RunFigures]) -> Figure | None:
    """CDF of each run's loop latency (sketch buckets), p50 dashed, p99 dotted; the axis ends at 2 x p99."""
    timed = [run for run in runs if run.latency.count]
    if not timed:
        return None
    figure, axis = plt.subplots(figsize=(10.0, 3.6))
    left, right = 0.0, 0.0
    for run in timed:
        values, fraction = run.latency.cdf()
        summary = run.latency.summary()
        (line,) = axis.step(values, fraction, where="post", linewidth=0.9, label=run.label)
        for value, style, name in ((summary.p50_ms, "--", "p50"), (summary.p99_ms, ":", "p99")):
            axis.axvline(
                value,
                color=line.get_color(),
                linestyle=style,
                linewidth=0.8,
                label=f"{run.label} {name} {value:.3g} ms",
            )
        axis.plot([], [], " ", label=f"{run.label} max {summary.max_ms:.3g} ms")
        left, right = min(left, float(values[0])), max(right, 2.0 * summary.p99_ms)
    if right > left:
        axis.set_xlim(left, right)
    axis.set_title("loop latency: command receive time - measurement receive time")
    axis.set_xlabel("latency (ms)")
    axis.set_ylabel("fraction of steps at or below")
    axis.set_ylim(0.0, 1.0)
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize=7, loc="lower right")
    figure.tight_layout()
    return figure


def write_plots(runs: Sequence[RunFigures], out: Path) -> dict[str, str]:
    """Writes the figures into ``out``; returns ``{name: file or reason it was not drawn}``."""
    out.mkdir(parents=True, exist_ok=True)
    for run in runs:
        run.finish()
    written: dict[str, str] = {}
    with drawing():
        for name in PLOTS:  # one figure at a time: drawn, saved and closed before the next is built
            figure = _latency_figure(runs) if name == "latency" else _figure(runs, name)
            if figure is None:
                written[name] = "not recorded in these bags"
                continue
            path = out / f"{name}.png"
            figure.savefig(path, dpi=_DPI)
            plt.close(figure)
            written[name] = str(path)
    return written
