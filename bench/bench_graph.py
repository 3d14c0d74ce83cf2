"""Benchmark of the ROS graph: real-time latency and deadline misses, lockstep throughput.

Figures, not pass/fail (``make bench``; never a test): every ROS process runs inside a private network
namespace (this script re-executes itself under ``unshare --net`` with ``lo`` up, through
``tests/netns_exec.py``), with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a ROS_DOMAIN_ID of its own.

0. The host floor, without ROS: the wake-up lateness of a bare 1 ms sleep loop (the share of wake-ups
   later than one period bounds the deadline-miss rate of any 1 kHz loop on this machine) and a bare UDP
   ping-pong between two processes.
1. Raw rclpy ping-pong between two processes (JointState out, echoed back, 1 kHz, EventsExecutor): the
   round-trip latency floor of this machine and middleware, measured in the same run.
2. Real time, separate processes (``smm-launch --clock-mode realtime``, case2, FPDESO, 1 kHz for 30 s) with
   the default graph (sim -> controller_node -> sim: two hops, two processes; controller_node samples the
   reference): deadline-miss rate (ticks at which the answer to the previous measurement had not arrived)
   and measurement-to-command latency p50/p99. Targets: p99 < 1 ms, misses < 1 %. For comparison, shorter:
   the fused chain with reference_node (three processes, reference one period ahead, off the path), the
   split chain (sim -> td -> fleso -> controller -> sim: four hops), and the default graph composed.
3. Lockstep throughput (case2), separate processes and ``--composed``, for the same layouts, in steps per
   wall second from the first step to the last (start-up excluded). Target: >= 2000 steps/s composed
   (default graph).

Exit code 0 whenever the measurements ran, even if a target is MISSED; non-zero only if a run failed.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
NETNS_EXEC = REPO / "tests" / "netns_exec.py"
PING_TOPIC = "bench_ping"
PONG_TOPIC = "bench_pong"
LATENCY_P99_TARGET_US = 1000.0
MISS_RATE_TARGET = 0.01
COMPOSED_TARGET_STEPS_PER_S = 2000.0
REALTIME_TORQUE_LIMIT = 20.0
"""Torque saturation of the plant in the real-time runs (N m; case2 needs a few N m)."""


def verdict(met: bool) -> str:
    return "met" if met else "MISSED"


# ------------------------------------------------------------------------------------ namespace re-exec


def reexec_in_private_netns(
    argv: list[str], script: str = __file__, domain_base: int = 200, domains: int = 30
) -> int:
    """Run ``script --inner argv`` in a private network namespace with only loopback (as the tests do)."""
    command = ["unshare", "--net"]
    if os.geteuid() != 0:
        command.append("--map-root-user")
    command += [
        "--",
        sys.executable,
        str(NETNS_EXEC),
        sys.executable,
        str(Path(script).resolve()),
        "--inner",
    ]
    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.setdefault("ROS_DOMAIN_ID", str(domain_base + os.getpid() % domains))
    try:
        return subprocess.run([*command, *argv], env=env, check=False).returncode
    except FileNotFoundError:
        print(
            f"{Path(script).stem}: 'unshare' (util-linux) is missing; cannot isolate the ROS processes",
            file=sys.stderr,
        )
        return 1


# ------------------------------------------------------------------------------------------- ping-pong


def pong(seconds: float) -> int:
    """Echo every ping back until ``seconds`` passed (run as its own process)."""
    import rclpy
    from rclpy.context import Context
    from sensor_msgs.msg import JointState
    from smm_msgs_py.qos import control_qos

    from smm_node_runtime import make_executor

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("bench_pong", context=context)
    publisher = node.create_publisher(JointState, PONG_TOPIC, control_qos())
    node.create_subscription(JointState, PING_TOPIC, publisher.publish, control_qos())
    executor = make_executor(context)
    executor.add_node(node)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    executor.shutdown()
    node.destroy_node()  # type: ignore[no-untyped-call]
    context.try_shutdown()
    return 0


def process_cpu_seconds(pid: int) -> float:
    """User + system CPU time a process has used so far (s), from /proc (Linux)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def ping_pong(seconds: float) -> dict[str, float]:
    """Round trips of a JointState at 1 kHz to a pong process and back (us)."""
    import rclpy
    from rclpy.clock import Clock, ClockType  # type: ignore[attr-defined]
    from rclpy.context import Context
    from sensor_msgs.msg import JointState
    from smm_msgs_py.qos import control_qos

    from smm_node_runtime import make_executor

    partner = subprocess.Popen(
        [
            sys.executable,
            str(Path(__file__).resolve()),
            "--inner",
            "--role",
            "pong",
            "--seconds",
            str(seconds + 30),
        ]
    )
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("bench_ping", context=context)
    sent: dict[int, int] = {}
    round_trips: list[int] = []

    def on_pong(msg: JointState) -> None:
        start = sent.pop(msg.header.stamp.nanosec, None)
        if start is not None:
            round_trips.append(time.monotonic_ns() - start)

    publisher = node.create_publisher(JointState, PING_TOPIC, control_qos())
    node.create_subscription(JointState, PONG_TOPIC, on_pong, control_qos())
    counter = [0]

    def tick() -> None:
        counter[0] += 1
        msg = JointState()
        msg.header.stamp.nanosec = counter[0]
        msg.name = ["alpha", "beta"]
        msg.position = [0.1, 0.2]
        msg.effort = [0.0, 0.0]
        sent[counter[0]] = time.monotonic_ns()
        publisher.publish(msg)

    executor = make_executor(context)
    executor.add_node(node)
    deadline = time.monotonic() + 30.0
    while publisher.get_subscription_count() == 0 or node.count_publishers(PONG_TOPIC) == 0:
        executor.spin_once(timeout_sec=0.05)
        if time.monotonic() > deadline:
            break
    time.sleep(0.5)  # let the reverse direction match too
    node.create_timer(1e-3, tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
    deadline = time.monotonic() + seconds
    partner_cpu_start = process_cpu_seconds(partner.pid)
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    partner_cpu = process_cpu_seconds(partner.pid) - partner_cpu_start
    executor.shutdown()
    node.destroy_node()  # type: ignore[no-untyped-call]
    context.try_shutdown()
    partner.terminate()
    partner.wait(timeout=30)
    samples = np.asarray(round_trips, dtype=np.float64) / 1e3
    return {
        "sent": float(counter[0]),
        "answered": float(samples.size),
        "echo_cpu_fraction": partner_cpu / seconds,
        "p50_us": float(np.percentile(samples, 50)) if samples.size else float("nan"),
        "p99_us": float(np.percentile(samples, 99)) if samples.size else float("nan"),
    }


# ------------------------------------------------------------------------------------------ host floor

UDP_PONG_ADDRESS = ("127.0.0.1", 45_001)


def udp_pong(seconds: float) -> int:
    """Echo every UDP datagram on loopback back to its sender until none came for ``seconds``."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(UDP_PONG_ADDRESS)
        sock.settimeout(seconds)
        try:
            while True:
                data, sender = sock.recvfrom(1024)
                sock.sendto(data, sender)
        except TimeoutError:
            return 0


def sleep_until_ns(deadline_ns: int) -> None:
    """Sleep until ``time.monotonic_ns()`` reaches ``deadline_ns`` (return at once if it has)."""
    remaining_ns = deadline_ns - time.monotonic_ns()
    if remaining_ns > 0:
        time.sleep(remaining_ns / 1e9)


def timer_floor(seconds: float, period: float = 1e-3) -> dict[str, float]:
    """Wake-up lateness of a bare sleep loop at ``period`` in this process (no ROS, no work).

    A loop that sleeps to absolute deadlines and does nothing else: the share of wake-ups later than one
    period after their deadline is a deadline-miss rate that no loop sleeping between its ticks can beat.
    """
    lateness_ns: list[int] = []
    period_ns = int(period * 1e9)
    deadline_ns = time.monotonic_ns()
    for _ in range(int(seconds / period)):
        deadline_ns += period_ns
        sleep_until_ns(deadline_ns)
        lateness_ns.append(time.monotonic_ns() - deadline_ns)
    late = np.asarray(lateness_ns, dtype=np.float64) / 1e3
    return {
        "late_fraction": float(np.mean(late > period * 1e6)),
        "p50_us": float(np.percentile(late, 50)),
        "p99_us": float(np.percentile(late, 99)),
    }


def udp_ping_pong(seconds: float, period: float = 1e-3) -> dict[str, float]:
    """Round trips of a 120-byte UDP datagram to an echo process and back at ``period`` (us; no ROS)."""
    partner = subprocess.Popen(
        [sys.executable, str(Path(__file__).resolve()), "--inner", "--role", "udp-pong", "--seconds", "5"]
    )
    round_trips: list[int] = []
    payload = bytes(120)
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.settimeout(1.0)
            started = time.monotonic()
            while True:  # until the echo process is bound
                sock.sendto(payload, UDP_PONG_ADDRESS)
                try:
                    sock.recv(1024)
                    break
                except (TimeoutError, ConnectionRefusedError):
                    if time.monotonic() - started > 30.0:
                        raise
            period_ns = int(period * 1e9)
            deadline_ns = time.monotonic_ns()
            for _ in range(int(seconds / period)):
                start = time.monotonic_ns()
                sock.sendto(payload, UDP_PONG_ADDRESS)
                sock.recv(1024)
                round_trips.append(time.monotonic_ns() - start)
                deadline_ns += period_ns
                sleep_until_ns(deadline_ns)
    finally:
        partner.wait(timeout=30)
    samples = np.asarray(round_trips, dtype=np.float64) / 1e3
    return {"p50_us": float(np.percentile(samples, 50)), "p99_us": float(np.percentile(samples, 99))}


# ---------------------------------------------------------------------------------------------- graph


def run_graph(
    workdir: Path,
    label: str,
    arguments: list[str],
    *,
    timeout_s: float,
    sim_yaml: str = "",
    extra_yaml: str = "",
) -> dict[str, Any] | None:
    """Run smm-launch with a stats file; return the simulator's statistics (None if the run failed).

    ``sim_yaml`` adds lines to the simulator's section of the parameter file, ``extra_yaml`` other sections.
    """
    stats = workdir / f"{label}.json"
    params = workdir / f"{label}.yaml"
    params.write_text(
        f'/**/smm_sim_node:\n  ros__parameters:\n    stats_file: "{stats}"\n    stats_period: 0.0\n'
        + sim_yaml
        + extra_yaml
    )
    log = workdir / f"{label}.log"
    command = [sys.executable, "-m", "smm_bringup.launcher", *arguments, "--params-file", str(params)]
    start = time.monotonic()
    with log.open("wb") as out:
        try:
            code = subprocess.run(
                command, stdout=out, stderr=subprocess.STDOUT, timeout=timeout_s, check=False
            ).returncode
        except subprocess.TimeoutExpired:
            code = -1
    if code != 0 or not stats.is_file():
        print(f"  {label}: smm-launch failed (exit {code}); log:\n{log.read_text(errors='replace')[-3000:]}")
        return None
    result: dict[str, Any] = json.loads(stats.read_text())
    result["launch_wall_s"] = time.monotonic() - start
    return result


HOPS = {"fused": 2, "split": 4}
"""Process boundaries a measurement crosses until its command is back at the plant, per chain layout."""

LAYOUTS = {
    "default": ["--chain", "fused", "--reference", "controller"],
    "fused + reference_node": ["--chain", "fused", "--reference", "node"],
    "split": ["--chain", "split", "--reference", "node"],
}
"""smm-launch arguments of each benchmarked layout; "default" is the graph smm-launch starts unasked."""


def report_realtime(
    stats: dict[str, Any],
    period: float,
    seconds: float,
    raw: dict[str, float],
    *,
    layout: str,
    composed: bool,
    targets: bool,
) -> None:
    """Print the figures of one real-time run (with the verdicts when ``targets``)."""
    steps = stats["steps"]
    misses = stats["deadline_misses"]
    rate = misses / steps if steps else float("nan")
    latency = stats["latency"]
    p99 = latency["p99_us"]
    miss_target = (
        f", target < {100 * MISS_RATE_TARGET:g} %: {verdict(rate < MISS_RATE_TARGET)}" if targets else ""
    )
    p99_target = (
        f" (target < {LATENCY_P99_TARGET_US:.0f} us: {verdict(p99 < LATENCY_P99_TARGET_US)})"
        if targets
        else ""
    )
    print(
        f"real time, {'composed' if composed else 'separate processes'}, {layout} graph, "
        f"{1 / period:.0f} Hz for {seconds:g} s: "
        f"{steps} steps, "
        f"deadline misses {misses} ({100 * rate:.2f} %{miss_target}), late ticks {stats['late_ticks']}, "
        f"zero-torque ticks {stats['stale_ticks']}"
    )
    hops = 0 if composed else HOPS[LAYOUTS[layout][1]]
    print(
        f"  measurement-to-command latency ({hops} inter-process hops): "
        f"p50 {latency['p50_us']:.0f} us, "
        f"p99 {p99:.0f} us{p99_target}, "
        f"max {latency['max_us']:.0f} us; {latency['count']:.0f} of {steps} measurements answered"
    )
    print(
        f"  ratio to the raw ping-pong round trip (2 hops): p50 x{latency['p50_us'] / raw['p50_us']:.1f}, "
        f"p99 x{p99 / raw['p99_us']:.1f}"
    )


def td_filter_yaml(period: float) -> str:
    """Parameter-file section giving the TD a filter factor h >= the control period (its constraint).

    A ``/**`` section reaches whichever node runs the TD (controller_node fused, td_node split).
    """
    if period <= 2e-3:
        return ""
    return f"/**:\n  ros__parameters:\n    td:\n      filter_factor: [{period}, {period}]\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument(
        "--role", choices=("bench", "pong", "udp-pong"), default="bench", help=argparse.SUPPRESS
    )
    parser.add_argument("--seconds", type=float, default=5.0, help=argparse.SUPPRESS)
    parser.add_argument(
        "--realtime-seconds", type=float, default=30.0, help="length of the 1 kHz real-time run (s)"
    )
    parser.add_argument(
        "--lockstep-seconds", type=float, default=5.0, help="simulated length of lockstep runs (s)"
    )
    arguments = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if arguments.role == "pong":
        return pong(arguments.seconds)
    if arguments.role == "udp-pong":
        return udp_pong(arguments.seconds)
    if not arguments.inner:
        forwarded = ["--realtime-seconds", str(arguments.realtime_seconds)]
        forwarded += ["--lockstep-seconds", str(arguments.lockstep_seconds)]
        return reexec_in_private_netns(forwarded)

    print(
        f"network interfaces: {[name for _, name in socket.if_nameindex()]}, "
        f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')}, "
        f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')}, "
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores"
    )
    failures = 0
    # The floor under every figure below: what this machine gives a loop with no ROS and no work at all.
    timer = timer_floor(10.0)
    print(
        f"host floor, bare 1 ms sleep loop (no ROS, no work): wake-up lateness p50 {timer['p50_us']:.0f} us, "
        f"p99 {timer['p99_us']:.0f} us; {100 * timer['late_fraction']:.2f} % of wake-ups later than one "
        "period (a 1 kHz loop that sleeps between its ticks misses at least this often)"
    )
    udp = udp_ping_pong(5.0)
    print(
        f"host floor, bare UDP ping-pong (2 processes, loopback, no ROS, 1 kHz): round trip "
        f"p50 {udp['p50_us']:.0f} us, p99 {udp['p99_us']:.0f} us"
    )
    raw = ping_pong(5.0)
    print(
        f"raw rclpy ping-pong (2 processes, JointState, 1 kHz): round trip p50 {raw['p50_us']:.0f} us, "
        f"p99 {raw['p99_us']:.0f} us ({raw['answered']:.0f}/{raw['sent']:.0f} answered)"
    )
    print(
        "  the echo process alone (one take + one publish per ms, no work) uses "
        f"{100 * raw['echo_cpu_fraction']:.0f} % of a core"
    )
    with tempfile.TemporaryDirectory(prefix="bench_graph_") as tmp:
        workdir = Path(tmp)
        # 1 kHz (FPDESO, case2, default graph) is the target; the other layouts for comparison, and the
        # default graph composed in one process (no inter-process hop at all).
        short = min(arguments.realtime_seconds, 10.0)
        realtime_runs = (
            ("default", False, arguments.realtime_seconds),
            ("fused + reference_node", False, short),
            ("split", False, short),
            ("default", True, short),
        )
        period = 1e-3
        for layout, composed, seconds in realtime_runs:
            command = ["--clock-mode", "realtime", "--scenario", "case2", "--algorithm", "fpdeso"]
            command += [
                *LAYOUTS[layout],
                "--duration",
                str(seconds),
                "--control-rate",
                str(round(1 / period)),
            ]
            command += ["--composed"] if composed else []
            stats = run_graph(
                workdir,
                f"realtime_{layout.replace(' + ', '_')}{'_composed' if composed else ''}",
                command,
                timeout_s=seconds + 120,
                # A real plant saturates; without it a loop run on late commands can drive the plant to Inf.
                sim_yaml=f"    torque_limit: [{REALTIME_TORQUE_LIMIT}, {REALTIME_TORQUE_LIMIT}]\n",
                extra_yaml=td_filter_yaml(period),
            )
            if stats is None:
                failures += 1
                continue
            print(f"[fpdeso, case2, torque limit +-{REALTIME_TORQUE_LIMIT:g} N m]")
            report_realtime(
                stats,
                period,
                seconds,
                raw,
                layout=layout,
                composed=composed,
                targets=not composed and layout == "default",
            )
            if not composed and layout == "default":
                print(
                    f"  beside the host floor: a bare sleep loop was late at "
                    f"{100 * timer['late_fraction']:.2f} % of its ticks, a bare UDP round trip's p99 was "
                    f"{udp['p99_us']:.0f} us"
                )
        rates: dict[str, float] = {}
        lockstep_runs = [
            (
                f"{placement}, {layout} graph",
                [*arguments_, *(["--composed"] if placement == "composed" else [])],
            )
            for layout, arguments_ in LAYOUTS.items()
            for placement in ("separate processes", "composed")
        ]
        for label, extra in lockstep_runs:
            stats = run_graph(
                workdir,
                "lockstep_" + label.replace(",", "").replace(" ", "_"),
                [
                    "--clock-mode",
                    "lockstep",
                    "--scenario",
                    "case2",
                    "--duration",
                    str(arguments.lockstep_seconds),
                    *extra,
                ],
                timeout_s=600,
            )
            if stats is None:
                failures += 1
                continue
            rates[label] = stats["steps_per_wall_second"]
            line = f"lockstep, {label}: {stats['steps']} steps at {rates[label]:.0f} steps/s"
            if label == "composed, default graph":
                met = rates[label] >= COMPOSED_TARGET_STEPS_PER_S
                line += f" (target >= {COMPOSED_TARGET_STEPS_PER_S:.0f}: {verdict(met)})"
            line += f", {rates[label] / 1000:.2f}x real time (launch to exit {stats['launch_wall_s']:.1f} s)"
            print(line)
        for layout in LAYOUTS:
            composed_rate, separate = (
                rates.get(f"composed, {layout} graph"),
                rates.get(f"separate processes, {layout} graph"),
            )
            if composed_rate and separate:
                print(f"  {layout} graph, composed / separate processes: x{composed_rate / separate:.2f}")
        default = rates.get("composed, default graph")
        for layout in list(LAYOUTS)[1:]:
            other = rates.get(f"composed, {layout} graph")
            if default and other:
                print(f"  composed, default / {layout} graph: x{default / other:.2f}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
