"""The main job (``make demo``): the paper's case 2 in lockstep through the real ROS 2 graph on the simulator.

For each controller asked for: runs the graph with ``smm-launch --record`` into an MCAP bag (``--bags``,
default ``bags/``), prints its eq. 42-45 indices beside the offline simulator's (same seed) and the paper's,
then analyses the bags side by side into ``--out`` (default ``out/demo``). See README.md, "Two commands".
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.errors import AnalysisError
from smm_analysis.metrics import METRICS, JointIndices, joint_indices
from smm_analysis.reproduction.paper_values import PAPER_CASE2
from smm_analysis.runs.commands import AnalyzeOptions, analyze
from smm_analysis.runs.indices import evaluate
from smm_analysis.runs.recorded import load_run, stamps_per_topic
from smm_analysis.scenarios import get_scenario
from smm_bag.errors import BagError
from smm_bag.manifest import RunManifest
from smm_bag.metadata import read_metadata
from smm_controller.laws import PAPER_LAWS, law_names

from smm_bringup.graph_nodes import NAMESPACE, SIM_NODE
from smm_bringup.graph_options import CHAIN_LAYOUTS, REFERENCE_PLACEMENTS, GraphOptions
from smm_bringup.launcher import arguments_from_options

DEMO_CONTROLLERS = PAPER_LAWS[:2]
"""FPDESO and its first baseline, FPD (the paper's case-2 comparison)."""
JOINTS = ("alpha", "beta")


class DemoError(AnalysisError):
    """The graph run failed or left no usable record."""


@dataclass(frozen=True)
class DemoRun:
    """Indices of one controller: through the graph and offline (same scenario and seed)."""

    controller: str
    graph: Mapping[str, JointIndices]
    offline: Mapping[str, JointIndices]
    steps: int
    wall_time: float
    bag: Path | None = None
    missing_steps: int = 0
    simulator_steps: int = 0
    recorded_stamps: Mapping[str, int] = dataclasses.field(default_factory=dict)
    """Per stepped topic, the simulator's step stamps found in the bag (== simulator_steps: nothing lost)."""
    published: Mapping[str, int] = dataclasses.field(default_factory=dict)
    """Per topic of the simulator, the messages it published (re-publications included)."""
    recorded_messages: Mapping[str, int] = dataclasses.field(default_factory=dict)
    """Per topic of the simulator, the messages in the bag (== published: nothing lost)."""

    @property
    def lost(self) -> dict[str, int]:
        """Per stepped topic, the simulator's steps missing from the bag (only topics that miss some)."""
        return shortfall(dict.fromkeys(self.recorded_stamps, self.simulator_steps), self.recorded_stamps)

    @property
    def unrecorded(self) -> dict[str, int]:
        """Per topic of the simulator, its messages missing from the bag (only topics that miss some)."""
        return shortfall(self.published, self.recorded_messages)


def shortfall(expected: Mapping[str, int], found: Mapping[str, int]) -> dict[str, int]:
    """Per topic, how many of ``expected`` are not in ``found`` (only topics that miss some)."""
    return {topic: n - found.get(topic, 0) for topic, n in expected.items() if found.get(topic, 0) != n}


def graph_command(options: GraphOptions) -> list[str]:
    """The ``smm-launch`` command line that starts the graph ``options`` describe."""
    return [sys.executable, "-m", "smm_bringup.launcher", *arguments_from_options(options)]


def run_graph(options: GraphOptions, bags_dir: Path) -> tuple[Path, int, dict[str, int]]:
    """Run the graph once with ``recorder_node`` recording.

    Returns:
        The bag folder, the simulator's steps and its published messages per topic.

    Raises:
        DemoError: ``smm-launch`` exited non-zero or wrote no bag or no simulator statistics.
    """
    bags_dir.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y%m%d_%H%M%S", time.gmtime())
    bag = (bags_dir / f"{options.scenario}_{options.algorithm}_{stamp}").resolve()
    suffix = 1
    while bag.exists():
        suffix += 1
        bag = bag.with_name(f"{options.scenario}_{options.algorithm}_{stamp}_{suffix}")
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    with tempfile.TemporaryDirectory(prefix="smm_demo_") as scratch:
        stats = Path(scratch) / "sim_stats.json"
        params = Path(scratch) / "sim_stats.yaml"
        key = f"/{NAMESPACE}/{SIM_NODE}"
        params.write_text(json.dumps({key: {"ros__parameters": {"stats_file": str(stats)}}}))
        recording = dataclasses.replace(
            options, record=str(bag), params_files=(*options.params_files, str(params))
        )
        code = subprocess.run(graph_command(recording), env=env, check=False)
        if code.returncode != 0:
            raise DemoError(
                f"smm-launch exited with code {code.returncode} for controller {options.algorithm}"
            )
        if not (bag / "metadata.yaml").is_file():
            raise DemoError(f"the recorder wrote no bag at {bag}")
        if not stats.is_file():
            raise DemoError(f"the simulator wrote no statistics ({stats})")
        written = json.loads(stats.read_text())
    published = {str(topic): int(n) for topic, n in written["published"].items()}
    return bag, int(written["steps"]), published


def recorded_messages(bag: Path, topics: Sequence[str]) -> dict[str, int]:
    """Messages in ``bag`` per topic of ``topics`` (its ``metadata.yaml`` counts; 0 for a topic not in it)."""
    metadata = read_metadata(bag)
    return {topic: info.message_count if (info := metadata.topic(topic)) else 0 for topic in topics}


def recorded_steps(bag: Path, steps: int) -> dict[str, int]:
    """Per stepped topic of ``bag``, how many of the simulator's ``steps`` stamps (k * period) it holds."""
    period_ns = RunManifest.from_custom_data(read_metadata(bag).custom_data).control_period_ns
    expected = {k * period_ns for k in range(steps)}
    return {topic: len(stamps & expected) for topic, stamps in stamps_per_topic(bag).items()}


def graph_indices(bag: Path, options: GraphOptions) -> DemoRun:
    """Indices of a recorded graph run (``smm-bag analyze``'s) and of the offline loop at the same steps.

    The recorded steps are those with a measurement, a reference and a command in the bag; the offline loop
    is evaluated at exactly those stamps, so the two agree to rounding when nothing was lost and the loss
    accounting says how many steps are missing when something was.

    Raises:
        DemoError: ``options`` name no scenario, or the bag's stamps are not the scenario's.
        BagError: The bag is unreadable or lacks the stack's topics.
    """
    if options.scenario is None or options.seed is None:
        raise DemoError("a demo run needs a scenario and a seed to compare with the offline loop")
    run = load_run(bag)
    chosen = get_scenario(options.scenario)
    if options.duration is not None:
        chosen = chosen.with_duration(options.duration)
    offline = run_closed_loop(chosen, options.algorithm, seed=options.seed, record_internals=False)
    index = np.searchsorted(offline.t_ns, run.t_ns)
    if np.any(index >= offline.t_ns.size) or not np.array_equal(offline.t_ns[index], run.t_ns):
        raise DemoError(f"{bag}: the recorded stamps are not the offline loop's: not the same scenario")
    commanded = offline.t_ns.size - 1  # the last measurement ends the run unanswered
    return DemoRun(
        controller=options.algorithm,
        graph=evaluate(run).joints,
        offline=joint_indices(
            run.t_ns, offline.desired_position[index], offline.position[index], offline.command_torque[index]
        ),
        steps=int(run.t_ns.size),
        wall_time=0.0,
        bag=bag,
        missing_steps=commanded - int(run.t_ns.size),
    )


def format_table(runs: Sequence[DemoRun]) -> str:
    """A plain-text table: per controller and joint, graph vs offline vs the paper (case 2 only)."""
    lines = [
        f"{'controller':10s} {'joint':6s} {'index':6s} {'graph':>11s} {'offline':>11s} {'paper':>9s}",
    ]
    for run in runs:
        paper_values = PAPER_CASE2.get(run.controller, {})
        for joint_index, joint in enumerate(JOINTS):
            for index in (row.name for row in METRICS if row.paper_equation):
                pair = paper_values.get(index)
                paper = pair[joint_index] if pair is not None else None
                paper_text = f"{paper:9.4g}" if paper is not None else f"{'-':>9s}"
                lines.append(
                    f"{run.controller:10s} {joint:6s} {index:6s} {getattr(run.graph[joint], index):11.5g} "
                    f"{getattr(run.offline[joint], index):11.5g} {paper_text}"
                )
    return "\n".join(lines)


def demo(
    controllers: Sequence[str],
    scenario: str,
    seed: int,
    duration: float | None,
    out_dir: Path,
    *,
    bags_dir: Path = Path("bags"),
    chain: Literal["fused", "split"] = GraphOptions.chain,
    reference: Literal["node", "controller"] = GraphOptions.reference,
) -> int:
    """Run the demo; return the process exit code."""
    out_dir.mkdir(parents=True, exist_ok=True)
    runs: list[DemoRun] = []
    for controller in controllers:
        print(
            f"[demo] {scenario} with {controller} through the ROS 2 graph (lockstep, {chain} chain, "
            f"reference sampled by the {reference}, seed {seed})",
            flush=True,
        )
        options = GraphOptions(
            clock_mode="lockstep",
            chain=chain,
            reference=reference,
            algorithm=controller,
            scenario=scenario,
            duration=duration,
            seed=seed,
        )
        start = time.perf_counter()
        try:
            bag, steps, published = run_graph(options, bags_dir)
            run = graph_indices(bag, options)
            run = dataclasses.replace(
                run,
                simulator_steps=steps,
                recorded_stamps=recorded_steps(bag, steps),
                published=published,
                recorded_messages=recorded_messages(bag, sorted(published)),
            )
        except (DemoError, AnalysisError, BagError) as error:
            print(f"[demo] error: {error}", file=sys.stderr)
            return 1
        wall = time.perf_counter() - start
        runs.append(dataclasses.replace(run, wall_time=wall))
        print(f"[demo] {run.steps} steps in {wall:.1f} s ({run.steps / wall:.0f} steps/s)", flush=True)
        if run.lost or run.missing_steps:
            print(
                f"[demo] error: the bag misses simulator steps: {run.lost or run.missing_steps}",
                file=sys.stderr,
            )
            return 1
        if run.unrecorded:
            print(
                f"[demo] error: the bag misses messages the simulator published: {run.unrecorded}",
                file=sys.stderr,
            )
            return 1
        print(
            f"[demo] every one of the simulator's {steps} steps is in the bag on "
            f"{', '.join(sorted(run.recorded_stamps))}; every message it published on "
            f"{', '.join(sorted(run.published))} too",
            flush=True,
        )
    print()
    print(format_table(runs))
    document = {
        "scenario": scenario,
        "seed": seed,
        "chain": chain,
        "reference": reference,
        "runs": {
            run.controller: {
                "steps": run.steps,
                "missing_steps": run.missing_steps,
                "simulator_steps": run.simulator_steps,
                "recorded_stamps": dict(run.recorded_stamps),
                "published": dict(run.published),
                "recorded_messages": dict(run.recorded_messages),
                "bag": str(run.bag),
                "graph": {joint: asdict(run.graph[joint]) for joint in JOINTS},
                "offline": {joint: asdict(run.offline[joint]) for joint in JOINTS},
            }
            for run in runs
        },
    }
    (out_dir / "metrics.json").write_text(json.dumps(document, indent=2))
    if len(runs) == 2 and {run.controller for run in runs} == set(DEMO_CONTROLLERS):
        by_name = {run.controller: run for run in runs}
        for joint in JOINTS:
            ours, theirs = by_name["fpdeso"].graph[joint].RMS, by_name["fpd"].graph[joint].RMS
            print(f"[demo] {joint}: FPDESO RMS is {100 * (1 - ours / theirs):.1f} % below FPD's")
    bags = [run.bag for run in runs if run.bag is not None]
    analysis = out_dir / "analysis"
    print(f"\n[demo] smm-bag analyze {' '.join(str(bag) for bag in bags)} --out {analysis}")
    code = analyze(AnalyzeOptions(bags=tuple(bags), out=analysis, quiet=True))
    if code != 0:
        return code
    print(f"[demo] bags in {bags_dir}; report {analysis / 'REPORT.md'}, figures in {analysis}")
    print(
        f"[demo] replay one: smm-bag play {bags[0]}; re-run with other gains: smm-bag rerun {bags[0]} "
        "--params-file F"
    )
    print(f"[demo] metrics.json (graph vs offline) in {out_dir}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The demo's command line (``--controllers``: the laws of ``smm_controller.laws.law_table()``)."""
    parser = argparse.ArgumentParser(prog="smm-demo", description=__doc__.splitlines()[0])
    parser.add_argument("--controllers", nargs="+", default=list(DEMO_CONTROLLERS), choices=law_names())
    parser.add_argument("--scenario", default="case2", choices=("step", "case1", "case2"))
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--duration", type=float, default=None, help="override the scenario length (s)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"))
    parser.add_argument("--bags", type=Path, default=Path("bags"), help="folder of the recorded bags")
    parser.add_argument(
        "--chain",
        choices=CHAIN_LAYOUTS,
        default=GraphOptions.chain,
        help="fused: TD, FLESO and law in controller_node; split: td_node and fleso_node too",
    )
    parser.add_argument(
        "--reference",
        choices=REFERENCE_PLACEMENTS,
        default=GraphOptions.reference,
        help="controller: controller_node samples the reference; node: reference_node publishes it",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m smm_bringup.demo [--controllers ...] [--scenario ...]``."""
    arguments = build_parser().parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return demo(
        arguments.controllers,
        arguments.scenario,
        arguments.seed,
        arguments.duration,
        arguments.out,
        bags_dir=arguments.bags,
        chain=arguments.chain,
        reference=arguments.reference,
    )


if __name__ == "__main__":
    sys.exit(main())
