"""Compare this tree with a baseline commit: a lockstep case-2 graph run and the offline loop, bit for bit.

Builds a git worktree of the baseline (default: the commit before the ControllerCore change) with its own
virtual environment, runs ``smm-launch --scenario case2 --record`` there and here (each in a private network
namespace, as the test suite does), and compares, per topic and per stamp, the decoded payloads of the
stack's topics (everything recorded but ``/diagnostics``, whose values are wall-clock figures; a wall-clock
retransmission counted once, the wall-clock counter rows of ``*_internals`` left out). The offline
closed loop (every law both trees know) is compared array by array, bit for bit. Exit 0 when all agree.

``--plant hardware``: lockstep runs of the bridge and the emulator's board instead, both ``--loop`` values,
on case 1, case 2 and case 2 with a scripted e-stop and re-arm (tools/compare_hardware.py): the topics as
above, and every feedback and command frame on the link, in order, bit for bit.

    .venv/bin/python tools/compare_baseline.py [--commit 362816c] [--out out/baseline]
    .venv/bin/python tools/compare_baseline.py --plant hardware --commit 053d24f --worktree ../i41-base
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from compare_hardware import INPUTS, LOOPS, compare_frames, hardware_run, private_netns
from smm_bag.cdr import decode_float64_multi_array, decode_joint_state, stamp_of
from smm_bag.reader import BagReader

HERE = Path(__file__).resolve().parents[1]
DEFAULT_COMMIT = "362816c"
IGNORED_TOPICS = ("/diagnostics", "/rosout", "/parameter_events")
WALL_CLOCK_ROWS = ("deadline_misses", "duplicates_answered")
"""Internals rows that count wall-clock events (a step longer than the period; a measurement the simulator
re-published after ``republish_period`` of wall time): they may differ run to run."""

OFFLINE_SNIPPET = """
import sys, numpy as np
try:
    from smm_controller.laws import law_names
    names = law_names()
except ImportError:
    from smm_controller.chain import CONTROLLER_NAMES as names
from smm_analysis.closed_loop import run_closed_loop
arrays = {}
for name in names:
    result = run_closed_loop("case2", name, seed=int(sys.argv[2]))
    for key, value in vars(result).items():
        if isinstance(value, np.ndarray):
            arrays[f"{name}/{key}"] = value
        elif key == "internals" and value is not None:
            for row, array in value.items():
                arrays[f"{name}/internals/{row}"] = np.asarray(array)
np.savez(sys.argv[1], **arrays)
"""


def run(command: list[str], **kwargs: object) -> None:
    """Runs ``command``, echoing it; raises on a non-zero exit."""
    print("+", " ".join(command), flush=True)
    subprocess.run(command, check=True, **kwargs)  # type: ignore[call-overload]


def baseline_tree(commit: str, path: Path) -> Path:
    """A worktree of ``commit`` at ``path`` with its virtual environment (made once, reused)."""
    if not (path / ".git").exists():
        run(["git", "-C", str(HERE), "worktree", "add", "--detach", str(path), commit])
    run(["make", "-C", str(path), "setup"], stdout=subprocess.DEVNULL)
    return path


def graph_run(tree: Path, out: Path, seed: int, domain_id: int) -> Path:
    """Records a lockstep case-2 run of ``tree``'s graph to ``out/bag``; returns the bag folder."""
    bag = out / "bag"
    if bag.exists():
        shutil.rmtree(bag)
    out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": str(domain_id)}
    python = str(tree / ".venv" / "bin" / "python")
    launch = [python, "-m", "smm_bringup.launcher", "--scenario", "case2", "--seed", str(seed)]
    run(private_netns([*launch, "--record", str(bag)]), env=env, cwd=tree)
    return bag


def offline_run(tree: Path, out: Path, seed: int) -> Path:
    """The offline closed loop of every law on case 2 in ``tree``, saved to ``out/offline.npz``."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "offline.npz"
    run([str(tree / ".venv" / "bin" / "python"), "-c", OFFLINE_SNIPPET, str(path), str(seed)], cwd=tree)
    return path


Payload = tuple[object, ...]


def decoded(type_name: str, data: bytes) -> Payload:
    """A message's content (CDR alignment padding is not content: the serializer leaves it uninitialised)."""
    if type_name == "std_msgs/msg/Float64MultiArray":
        array = decode_float64_multi_array(data)
        return (array.dims, array.data_offset, array.data)
    if type_name == "sensor_msgs/msg/JointState":
        state = decode_joint_state(data)
        return (state.stamp_ns, state.name, state.position, state.velocity, state.effort)
    return (type_name, stamp_of(type_name, data), data if stamp_of(type_name, data) is None else b"")


def payloads(bag: Path) -> dict[str, dict[int | None, list[Payload]]]:
    """``{topic: {stamp ns: [decoded payloads, distinct, in log order]}}`` of every compared topic.

    A retransmission (the simulator re-publishes an unanswered measurement after ``republish_period`` of
    wall time; the controller answers it again) repeats a payload: kept once.
    """
    found: dict[str, dict[int | None, list[Payload]]] = defaultdict(lambda: defaultdict(list))
    with BagReader(bag) as reader:
        for message in reader.messages():
            if message.topic in IGNORED_TOPICS:
                continue
            content = decoded(message.type, message.data)
            stamp = stamp_of(message.type, message.data)
            if content not in found[message.topic][stamp]:
                found[message.topic][stamp].append(content)
    return found


def without_wall_clock_rows(payload: Payload) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """An internals payload's labels and values, the wall-clock rows left out."""
    dims, _, data = payload
    assert isinstance(dims, tuple) and isinstance(data, tuple)
    labels = dims[0][0].partition(":")[2].split(",") if dims else []
    kept = [row for row, label in enumerate(labels) if label not in WALL_CLOCK_ROWS]
    width = len(data) // max(len(labels), 1)
    values = tuple(v for row in kept for v in data[row * width : (row + 1) * width])
    return tuple(labels[row] for row in kept), values


def compare_bags(before: Path, after: Path) -> list[str]:
    """Differences between two recorded runs, per topic and stamp (empty: equal)."""
    problems: list[str] = []
    old, new = payloads(before), payloads(after)
    for topic in sorted(set(old) | set(new)):
        a, b = old.get(topic, {}), new.get(topic, {})
        common = set(a) & set(b)
        only = (set(a) | set(b)) - common
        stamps = [s for s in common if s is not None]
        first, last = min(stamps, default=None), max(stamps, default=None)
        at_the_ends = (
            first is not None
            and last is not None
            and all(s is not None and not first <= s <= last for s in only)
        )
        if only and not at_the_ends:
            problems.append(f"{topic}: stamps differ ({len(a)} before, {len(b)} after)")
            continue
        if only:  # the recorder matched after the start or stopped before the last outputs: not the graph
            print(f"  {topic}: {len(only)} stamps at the run's start or end in one run only: left out")
        a, b = {s: a[s] for s in common}, {s: b[s] for s in common}
        differing = [stamp for stamp in a if a[stamp] != b[stamp]]
        if topic.endswith("internals"):
            strip = without_wall_clock_rows
            differing = [s for s in differing if set(map(strip, a[s])) != set(map(strip, b[s]))]
        messages = sum(len(v) for v in a.values())
        status = "equal" if not differing else f"{len(differing)} stamps DIFFER (first {differing[0]})"
        print(f"  {topic}: {len(a)} stamps, {messages} messages: {status}")
        if differing:
            problems.append(f"{topic}: {len(differing)} stamps differ")
    return problems


def compare_offline(before: Path, after: Path) -> list[str]:
    """Differences between two offline runs, array by array (bit for bit; NaN equals NaN)."""
    problems: list[str] = []
    with np.load(before) as a, np.load(after) as b:
        for key in sorted(set(a.files) & set(b.files)):
            same = a[key].shape == b[key].shape and a[key].tobytes() == b[key].tobytes()
            if not same:
                problems.append(f"offline {key}: differs")
        only = sorted(set(a.files) ^ set(b.files))
        laws = sorted({key.split("/")[0] for key in a.files})
        print(f"  offline: {len(set(a.files) & set(b.files))} arrays of {', '.join(laws)} compared")
        if only:
            print(f"  offline: arrays in one tree only: {', '.join(only)}")
    return problems


def compare_hardware_runs(args: argparse.Namespace, out: Path) -> int:
    """Runs (unless ``--compare-only``) and compares the lockstep hardware inputs; exit 0 when all agree."""
    loops = LOOPS if args.loop == "both" else (args.loop,)
    names = [name for name in args.inputs.split(",") if name]
    unknown = sorted(set(names) - set(INPUTS))
    if unknown:
        print(f"unknown inputs {unknown}: known {sorted(INPUTS)}", file=sys.stderr)
        return 2
    trees = {"before": (args.worktree or out / f"tree-{args.commit}").resolve(), "after": HERE}
    if not args.compare_only:
        baseline_tree(args.commit, trees["before"])
    problems: list[str] = []
    for name in names:
        for loop in loops:
            runs = {}
            for side, tree in trees.items():
                where = out / "hardware" / side
                if args.compare_only:
                    runs[side] = (where / f"{loop}-{name}" / "bag", where / f"{loop}-{name}" / "frames.json")
                else:
                    runs[side] = hardware_run(
                        tree, where, loop=loop, name=name, seed=args.seed, domain_id=args.domain_id
                    )
            print(f"hardware lockstep, --loop {loop}, {name}, seed {args.seed}: {args.commit} vs this tree")
            found = compare_bags(runs["before"][0], runs["after"][0])
            found += compare_frames(runs["before"][1], runs["after"][1])
            problems += [f"{loop} {name}: {problem}" for problem in found]
    for problem in problems:
        print(f"DIFFERENT: {problem}")
    print("hardware comparison:", "EQUAL" if not problems else f"{len(problems)} differences")
    return 0 if not problems else 1


def main(argv: list[str] | None = None) -> int:
    """Builds, runs and compares; exit 0 when both runs agree, 1 otherwise."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commit", default=DEFAULT_COMMIT, help="baseline commit (default %(default)s)")
    parser.add_argument("--worktree", type=Path, help="baseline worktree (default: OUT/tree-COMMIT)")
    parser.add_argument("--out", type=Path, default=HERE / "out" / "baseline")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--domain-id", type=int, default=77, help="ROS_DOMAIN_ID of both runs")
    parser.add_argument("--compare-only", action="store_true", help="compare the runs already in OUT")
    parser.add_argument("--plant", choices=("sim", "hardware"), default="sim", help="the graph compared")
    parser.add_argument(
        "--loop", choices=(*LOOPS, "both"), default="both", help="hardware: the bridge's loop"
    )
    parser.add_argument(
        "--inputs", default=",".join(INPUTS), help=f"hardware: comma-separated of {', '.join(INPUTS)}"
    )
    args = parser.parse_args(argv)
    out: Path = args.out.resolve()
    if args.plant == "hardware":
        return compare_hardware_runs(args, out)
    results = {name: (out / name / "bag", out / name / "offline.npz") for name in ("before", "after")}
    if not args.compare_only:
        tree = baseline_tree(args.commit, (args.worktree or out / f"tree-{args.commit}").resolve())
        for name, root in (("before", tree), ("after", HERE)):
            results[name] = (
                graph_run(root, out / name, args.seed, args.domain_id),
                offline_run(root, out / name, args.seed),
            )
    print(f"lockstep case2, seed {args.seed}: {args.commit} (before) vs this tree (after)")
    problems = compare_bags(results["before"][0], results["after"][0])
    problems += compare_offline(results["before"][1], results["after"][1])
    for problem in problems:
        print(f"DIFFERENT: {problem}")
    print("baseline comparison:", "EQUAL" if not problems else f"{len(problems)} differences")
    return 0 if not problems else 1


if __name__ == "__main__":
    sys.exit(main())
