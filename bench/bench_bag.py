"""Bags: recording at the graph's 1 kHz (published vs written per topic), and analysis time of a long bag.

Run by ``make bench``. Part 1 starts ``recorder_node`` in its own process and publishes the graph's topics
(``joint_states``, ``ground_truth``, ``reference``, ``torque_command``, ``controller_internals``, ``/clock``)
at 1 kHz for ``--record-seconds`` (60) from this process, with the stack's QoS, then waits until every
publisher's samples are acknowledged, stops the recorder with SIGINT and prints per topic the messages
published, written and the recorder's stamp gaps. Part 2 writes a ``--analysis-minutes`` (10) case2 run of
the offline loop as a bag (every chain internal included) and times ``smm-bag analyze``'s load and
evaluation (target < 30 s), with messages per second. Part 3 records the lockstep case2 graph
(``smm-launch --record``, separate processes) ``--graph-runs`` (3) times per chain layout for
``--graph-seconds`` (5) and prints, per run, whether every simulator step is on every stepped topic
(distinct stamps against the simulator's step count, as ``make demo`` checks). ROS runs in a private network
namespace (the script re-executes itself under ``unshare --net`` with ``lo`` up). Figures only; nothing
asserts on time.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Literal

HERE = Path(__file__).resolve().parent
ANALYSIS_TARGET_S = 30.0


def record_at_1khz(seconds: float, workdir: Path) -> None:
    import rclpy
    from rclpy.context import Context
    from rclpy.duration import Duration
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from smm_bag.cdr import encode_float64_multi_array, encode_joint_state
    from smm_bag.loss import loss_from_json
    from smm_bag.metadata import read_metadata
    from smm_msgs_py.qos import qos_for_topic
    from std_msgs.msg import Float64MultiArray

    bag = workdir / "recorded_1khz"
    recorder = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "smm_bag.recorder_node",
            "--ros-args",
            "-r",
            "__ns:=/smm",
            "-p",
            f"output:={bag}",
        ],
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("bench_publisher", context=context)
    names = ["alpha", "beta"]
    quantities = [f"q{i}" for i in range(24)]  # about the fused controller's internals
    topics = {
        "/smm/joint_states": (JointState, "joint_states"),
        "/smm/ground_truth": (JointState, "ground_truth"),
        "/smm/reference": (Float64MultiArray, "reference"),
        "/smm/torque_command": (Float64MultiArray, "torque_command"),
        "/smm/controller_internals": (Float64MultiArray, "controller_internals"),
        "/clock": (Clock, "/clock"),
    }
    publishers = {t: node.create_publisher(kind, t, qos_for_topic(rel)) for t, (kind, rel) in topics.items()}
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and any(p.get_subscription_count() == 0 for p in publishers.values()):
        time.sleep(0.05)
    time.sleep(0.5)
    published = dict.fromkeys(publishers, 0)
    steps = round(seconds * 1000)
    joint = ("joint:alpha,beta", 2, 2)
    start = time.monotonic()
    late = 0
    for k in range(steps):
        stamp = (k + 1) * 1_000_000
        stamp_dim = (f"stamp_ns:{stamp}", 1, 1)
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = divmod(stamp, 1_000_000_000)
        messages = {
            "/clock": clock,
            "/smm/joint_states": encode_joint_state(stamp, names, [k * 1e-6, 0.0], [], [1.0, 2.0]),
            "/smm/ground_truth": encode_joint_state(stamp, names, [k * 1e-6, 0.0], [0.0, 0.0], [1.0, 2.0]),
            "/smm/reference": encode_float64_multi_array(
                [("order:position,velocity,acceleration", 3, 6), joint, stamp_dim], [0.0] * 6
            ),
            "/smm/torque_command": encode_float64_multi_array([joint, stamp_dim], [1.0, 2.0]),
            "/smm/controller_internals": encode_float64_multi_array(
                [("quantity:" + ",".join(quantities), 24, 48), joint, stamp_dim], [0.5] * 48
            ),
        }
        for topic, message in messages.items():
            publishers[topic].publish(message)
            published[topic] += 1
        pause = start + (k + 1) * 0.001 - time.monotonic()
        if pause > 0:
            time.sleep(pause)
        else:
            late += 1
    wall = time.monotonic() - start
    acked = all(p.wait_for_all_acked(Duration(seconds=10)) for p in publishers.values())
    node.destroy_node()  # type: ignore[no-untyped-call]
    context.try_shutdown()
    time.sleep(1.0)
    os.killpg(recorder.pid, signal.SIGINT)
    _, log = recorder.communicate(timeout=60)
    metadata = read_metadata(bag)
    written = {topic.name: topic.message_count for topic in metadata.topics}
    loss = loss_from_json(metadata.custom_data.get("smm.loss", "{}"))
    print(
        f"recording: {steps} steps of 6 topics in {wall:.1f} s ({steps / wall:.0f} steps/s, {late} late), "
        f"all acknowledged: {acked}, recorder exit {recorder.returncode}"
    )
    print(f"{'topic':28s} {'published':>10s} {'written':>10s} {'lost':>6s} {'stamp gaps':>10s}")
    total_lost = 0
    for topic, count in published.items():
        got = written.get(topic, 0)
        total_lost += count - got
        gaps = loss.get(topic, {}).get("stamp_gaps", "-")
        print(f"{topic:28s} {count:10d} {got:10d} {count - got:6d} {gaps!s:>10s}")
    print(
        f"recording at 1 kHz for {seconds:g} s: {'nothing lost' if total_lost == 0 else f'{total_lost} LOST'}"
    )
    if recorder.returncode != 0:
        print(log[-2000:])


def graph_recordings(runs: int, seconds: float, workdir: Path) -> None:
    """Record the lockstep case2 graph (processes) ``runs`` times per chain; steps found per topic."""
    from smm_bringup.demo import recorded_messages, recorded_steps, run_graph, shortfall
    from smm_bringup.graph_options import GraphOptions

    layouts: tuple[tuple[Literal["fused", "split"], Literal["controller", "node"]], ...] = (
        ("fused", "controller"),
        ("split", "node"),
    )
    for chain, reference in layouts:
        for run in range(runs):
            options = GraphOptions(
                clock_mode="lockstep",
                chain=chain,
                reference=reference,
                scenario="case2",
                duration=seconds,
                seed=run,
            )
            start = time.perf_counter()
            bag, steps, published = run_graph(options, workdir / "graph_bags")
            wall = time.perf_counter() - start
            found = recorded_steps(bag, steps)
            lost = shortfall(dict.fromkeys(found, steps), found)
            unrecorded = shortfall(published, recorded_messages(bag, sorted(published)))
            print(
                f"lockstep graph ({chain} chain) run {run + 1}: {steps} simulator steps in {wall:.1f} s, "
                f"{len(found)} stepped topics in the bag: "
                + ("every step on every topic" if not lost else f"MISSING {lost}")
                + "; the simulator's published messages: "
                + ("all in the bag" if not unrecorded else f"MISSING {unrecorded}")
            )


def analysis_time(minutes: float, workdir: Path) -> None:
    from smm_analysis.closed_loop import run_closed_loop
    from smm_analysis.runs.from_trajectory import write_trajectory_bag
    from smm_analysis.runs.indices import evaluate
    from smm_analysis.runs.recorded import load_run
    from smm_analysis.scenarios import get_scenario

    start = time.perf_counter()
    trajectory = run_closed_loop(get_scenario("case2").with_duration(60.0 * minutes), "fpdeso", seed=0)
    simulated = time.perf_counter() - start
    bag = workdir / "long"
    start = time.perf_counter()
    metadata = write_trajectory_bag(trajectory, bag)
    written = time.perf_counter() - start
    del trajectory
    start = time.perf_counter()
    run = load_run(bag)
    loaded = time.perf_counter() - start
    evaluate(run)
    total = time.perf_counter() - start
    count = metadata.message_count
    size = sum(p.stat().st_size for p in bag.iterdir()) / 2**20
    print(
        f"analysis of a {minutes:g}-minute 1 kHz bag ({count} messages, {size:.0f} MiB; "
        f"offline run {simulated:.0f} s, "
        f"bag written in {written:.0f} s = {count / written:,.0f} msg/s): read+decode {loaded:.1f} s, "
        f"total {total:.1f} s = {count / total:,.0f} msg/s; target < {ANALYSIS_TARGET_S:g} s: "
        f"{'met' if total < ANALYSIS_TARGET_S else 'MISSED'}"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--record-seconds", type=float, default=60.0)
    parser.add_argument("--analysis-minutes", type=float, default=10.0)
    parser.add_argument("--graph-runs", type=int, default=3, help="recorded lockstep graph runs per chain")
    parser.add_argument("--graph-seconds", type=float, default=5.0, help="plant seconds of each graph run")
    arguments = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if not arguments.inner:
        forwarded = ["--record-seconds", str(arguments.record_seconds)]
        forwarded += ["--analysis-minutes", str(arguments.analysis_minutes)]
        forwarded += [
            "--graph-runs",
            str(arguments.graph_runs),
            "--graph-seconds",
            str(arguments.graph_seconds),
        ]
        from bench_graph import reexec_in_private_netns

        return reexec_in_private_netns(forwarded, __file__, domain_base=170)
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory(prefix="bench_bag_") as directory:
        workdir = Path(directory)
        if arguments.record_seconds > 0:
            record_at_1khz(arguments.record_seconds, workdir)
        if arguments.graph_runs > 0:
            graph_recordings(arguments.graph_runs, arguments.graph_seconds, workdir)
        if arguments.analysis_minutes > 0:
            analysis_time(arguments.analysis_minutes, workdir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
