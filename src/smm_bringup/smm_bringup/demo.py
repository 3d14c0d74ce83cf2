"""The main job: the full closed loop on the simulator, through the real ROS 2 graph.

``make demo`` (or ``python -m smm_bringup.demo``) starts the node graph with ``smm-launch`` (one OS process
per node: the simulator, and controller_node sampling the reference and running TD -> FLESO -> law, the
default graph; ``--chain split`` adds the TD and FLESO nodes, ``--reference node`` the reference_node),
runs the paper's case 2
(sinusoid, sensor noise, eq. 46 disturbance, +10 % inertia error) in lockstep for each controller asked
for, has the simulator record every sample, then prints the paper's indices (eq. 42-45) of the graph run
beside the offline simulator's for the same seed (they agree: a lockstep run is deterministic) and beside
the paper's numbers.

Outputs go to ``--out`` (default ``out/demo``): ``<controller>.npz`` (the simulator's record) and
``metrics.json``. DDS stays on loopback unless ``ROS_AUTOMATIC_DISCOVERY_RANGE`` was set by the caller.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from smm_analysis.closed_loop import run_closed_loop
from smm_analysis.errors import AnalysisError
from smm_analysis.metrics import JointIndices, joint_indices
from smm_analysis.paper_values import PAPER_CASE2
from smm_analysis.scenarios import get_scenario

from smm_bringup.graph import CHAIN_LAYOUTS, REFERENCE_PLACEMENTS, GraphOptions
from smm_bringup.launcher import arguments_from_options

DEMO_CONTROLLERS = ("fpdeso", "fpd")
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


def graph_command(options: GraphOptions) -> list[str]:
    """The ``smm-launch`` command line that starts the graph ``options`` describe."""
    return [sys.executable, "-m", "smm_bringup.launcher", *arguments_from_options(options)]


def run_graph(options: GraphOptions, out_dir: Path) -> Path:
    """Run the graph once, the simulator recording; return the path of its record (.npz).

    Raises:
        DemoError: ``smm-launch`` exited non-zero or wrote no record.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    record = (out_dir / f"{options.algorithm}.npz").resolve()
    record.unlink(missing_ok=True)
    params = out_dir / f"{options.algorithm}.record.yaml"
    params.write_text(f'/**/smm_sim_node:\n  ros__parameters:\n    record_file: "{record}"\n')
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    recording = dataclasses.replace(options, params_files=(*options.params_files, str(params)))
    code = subprocess.run(graph_command(recording), env=env, check=False)
    if code.returncode != 0:
        raise DemoError(f"smm-launch exited with code {code.returncode} for controller {options.algorithm}")
    if not record.is_file():
        raise DemoError(f"the simulator wrote no record at {record}")
    return record


def graph_indices(record_path: Path, options: GraphOptions) -> DemoRun:
    """Indices of a recorded graph run and of the offline loop, both over the N commanded intervals.

    Raises:
        DemoError: ``options`` name no scenario, or the record's stamps are not the scenario's.
    """
    if options.scenario is None or options.seed is None:
        raise DemoError("a demo run needs a scenario and a seed to compare with the offline loop")
    record = np.load(record_path)
    steps = int(record["command"].shape[0])
    chosen = get_scenario(options.scenario)
    if options.duration is not None:
        chosen = chosen.with_duration(options.duration)
    offline = run_closed_loop(chosen, options.algorithm, seed=options.seed, record_internals=False)
    if not np.array_equal(record["stamp_ns"][:steps], offline.t_ns[:steps]):
        raise DemoError("the graph's stamps differ from the offline loop's: not the same scenario")
    t_ns = offline.t_ns[:steps]
    desired = offline.desired_position[:steps]
    return DemoRun(
        controller=options.algorithm,
        graph=joint_indices(t_ns, desired, record["position"][:steps], record["command"]),
        offline=joint_indices(t_ns, desired, offline.position[:steps], offline.command_torque[:steps]),
        steps=steps,
        wall_time=0.0,
    )


def format_table(runs: Sequence[DemoRun]) -> str:
    """A plain-text table: per controller and joint, graph vs offline vs the paper (case 2 only)."""
    lines = [
        f"{'controller':10s} {'joint':6s} {'index':6s} {'graph':>11s} {'offline':>11s} {'paper':>9s}",
    ]
    for run in runs:
        paper_values = PAPER_CASE2.get(run.controller, {})
        for joint_index, joint in enumerate(JOINTS):
            for index in ("Ma", "Ave", "RMS", "eps_u"):
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
    chain: Literal["fused", "split"] = GraphOptions.chain,
    reference: Literal["node", "controller"] = GraphOptions.reference,
) -> int:
    """Run the demo; return the process exit code."""
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
            run = graph_indices(run_graph(options, out_dir), options)
        except (DemoError, AnalysisError) as error:
            print(f"[demo] error: {error}", file=sys.stderr)
            return 1
        wall = time.perf_counter() - start
        runs.append(DemoRun(run.controller, run.graph, run.offline, run.steps, wall))
        print(f"[demo] {run.steps} steps in {wall:.1f} s ({run.steps / wall:.0f} steps/s)", flush=True)
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
                "graph": {joint: asdict(run.graph[joint]) for joint in JOINTS},
                "offline": {joint: asdict(run.offline[joint]) for joint in JOINTS},
            }
            for run in runs
        },
    }
    (out_dir / "metrics.json").write_text(json.dumps(document, indent=2))
    if len(runs) == 2 and {run.controller for run in runs} == {"fpdeso", "fpd"}:
        by_name = {run.controller: run for run in runs}
        for joint in JOINTS:
            ours, theirs = by_name["fpdeso"].graph[joint].RMS, by_name["fpd"].graph[joint].RMS
            print(f"[demo] {joint}: FPDESO RMS is {100 * (1 - ours / theirs):.1f} % below FPD's")
    print(f"[demo] records and metrics.json in {out_dir}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``python -m smm_bringup.demo [--controllers ...] [--scenario ...]``."""
    parser = argparse.ArgumentParser(prog="smm-demo", description=__doc__.splitlines()[0])
    parser.add_argument(
        "--controllers", nargs="+", default=list(DEMO_CONTROLLERS), choices=("fpdeso", "fpd", "pid", "npd")
    )
    parser.add_argument("--scenario", default="case2", choices=("step", "case1", "case2"))
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--duration", type=float, default=None, help="override the scenario length (s)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"))
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
    arguments = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    return demo(
        arguments.controllers,
        arguments.scenario,
        arguments.seed,
        arguments.duration,
        arguments.out,
        chain=arguments.chain,
        reference=arguments.reference,
    )


if __name__ == "__main__":
    sys.exit(main())
