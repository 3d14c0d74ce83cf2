"""The recorder's memory under the soak's load, in minutes instead of an hour.

    python tools/recorder_memory.py --out out/recmem        # kills, stops, holds of 1-3 s: 9 minutes
    python tools/recorder_memory.py --skip respawn --skip stop --phase 200 --every 40 \
        --stall-seconds 1,2,4,8,12 --quiet 40 --drops       # the ladder of holds of docs/SOAK.md: 5 minutes

``recorder_node`` (the soak's parameters; ``--param``, ``--env`` add to them) records a synthetic publisher
of the direct loop's five topics (``joint_states``, ``torque_command``, ``reference``,
``controller_internals``, ``hw_bridge_internals``) at ``--rate`` Hz, in a private network namespace. After
a warm-up, three phases of ``--phase`` seconds each repeat one event every ``--every`` seconds: the
publisher killed (SIGKILL) and started again (a new participant, as the soak's kill of ``direct_loop``),
the recorder stopped (SIGSTOP/SIGCONT: every thread of it), its executor held in a callback (the
middleware's threads go on receiving), each for ``--stall-seconds`` in turn. Then a quiet phase. The
recorder runs inside a probe that samples, every ``--sample-every`` s: RSS (anonymous, file, shared
memory), glibc's arenas (``malloc_info``: size and free, per arena), the RSS of large mappings, Python's
allocated blocks (tracemalloc's total with ``--tracemalloc``) and the threads; ``--trim-every`` has it call
``malloc_trim(0)``. Prints the curve with the events, the growth per phase and the recorder's loss report
(``--drops``: the samples missing in the bag, by time); figures only, nothing is judged (docs/SOAK.md,
"The recorder's memory").
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
HOLD_FILE = "hold_s"
TRIM_FILE = "trim.txt"
SAMPLES_FILE = "samples.jsonl"
EVENTS_FILE = "events.jsonl"
NAMESPACE = "/smm"
_HEAP = re.compile(r'<heap nr="(\d+)">(.*?)</heap>', re.S)
_FREE = re.compile(r'<total type="(?:fast|rest)" count="\d+" size="(\d+)"/>')
_SYSTEM = re.compile(r'<system type="current" size="(\d+)"/>')
_MAPPING = re.compile(r"[0-9a-f]+-[0-9a-f]+ ")
_STATUS_FIELDS = ("VmRSS", "RssAnon", "RssFile", "RssShmem", "Threads")


# ------------------------------------------------------------------------------ the probe (recorder side)


def glibc_arenas() -> list[tuple[int, int]]:
    """``(system, free)`` bytes of every glibc arena (``malloc_info``), main arena first; [] elsewhere."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.fopen.restype = ctypes.c_void_p
        libc.fopen.argtypes = [ctypes.c_char_p, ctypes.c_char_p]
        libc.fclose.argtypes = [ctypes.c_void_p]
        libc.malloc_info.argtypes = [ctypes.c_int, ctypes.c_void_p]
    except (OSError, AttributeError):
        return []
    with tempfile.NamedTemporaryFile(suffix=".xml") as file:
        stream = libc.fopen(file.name.encode(), b"w")
        if not stream:
            return []
        libc.malloc_info(0, stream)
        libc.fclose(stream)
        text = Path(file.name).read_text()
    arenas = []
    for _, body in _HEAP.findall(text):
        system = _SYSTEM.search(body)
        free = sum(int(size) for size in _FREE.findall(body))
        arenas.append((int(system.group(1)) if system else 0, free))
    return arenas


def proc_status(pid: int | str = "self") -> dict[str, int]:
    """``VmRSS``, ``RssAnon``, ``RssFile``, ``RssShmem`` (KiB) and ``Threads`` from /proc/PID/status."""
    values = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, rest = line.partition(":")
        if key in _STATUS_FIELDS:
            values[key] = int(rest.split()[0])
    return values


def mappings(pid: int | str = "self") -> dict[str, Any]:
    """RSS by mapping (KiB): /dev/shm files, ``[heap]``, anonymous mappings of 1 MiB RSS or more by address.

    Fast DDS's shared-memory segments and port queues are /dev/shm files; glibc's thread arenas are
    anonymous mappings of up to 64 MiB, and so are large buffers.
    """
    shm_count = shm_rss = heap = 0
    anonymous: dict[str, int] = {}
    name = ""
    for line in Path(f"/proc/{pid}/smaps").read_text().splitlines():
        if _MAPPING.match(line):
            fields = line.split()
            name = fields[5] if len(fields) >= 6 else f"anon@{fields[0].split('-')[0]}"
            shm_count += name.startswith("/dev/shm/")
        elif line.startswith("Rss:"):
            rss = int(line.split()[1])
            if name.startswith("/dev/shm/"):
                shm_rss += rss
            elif name == "[heap]":
                heap += rss
            elif name.startswith("anon@") and rss >= 1024:
                anonymous[name[5:]] = rss
    return {"shm_maps": shm_count, "shm_rss": shm_rss, "heap_rss": heap, "anon": anonymous}


def sample(start: float) -> dict[str, Any]:
    """One sample of this process's memory."""
    import tracemalloc  # noqa: PLC0415

    arenas = glibc_arenas()
    return {
        "t": round(time.monotonic() - start, 2),
        **proc_status(),
        **mappings(),
        "arenas": arenas,
        "py_blocks": sys.getallocatedblocks(),
        "traced": tracemalloc.get_traced_memory()[0] if tracemalloc.is_tracing() else None,
    }


def probe(out: Path, every_s: float, recorder_args: Sequence[str]) -> int:
    """Runs ``recorder_node`` with ``recorder_args`` in this process, sampling it into ``out``."""
    from smm_bag import recorder_node  # noqa: PLC0415

    start = time.monotonic()

    def sampler() -> None:
        with (out / SAMPLES_FILE).open("a") as file:
            while True:
                file.write(json.dumps(sample(start)) + "\n")
                file.flush()
                time.sleep(every_s)

    def hold(_signum: int, _frame: object) -> None:
        time.sleep(float((out / HOLD_FILE).read_text()))  # in the main thread: the executor waits

    def trim(_signum: int, _frame: object) -> None:
        began = time.perf_counter()
        released = ctypes.CDLL("libc.so.6").malloc_trim(0)
        with (out / TRIM_FILE).open("a") as file:
            took_ms = 1e3 * (time.perf_counter() - began)
            file.write(f"malloc_trim(0) returned {released} in {took_ms:.1f} ms\n")

    signal.signal(signal.SIGUSR1, hold)
    signal.signal(signal.SIGUSR2, trim)
    threading.Thread(target=sampler, daemon=True, name="memory-probe").start()
    return recorder_node.main(["recorder_node", *recorder_args])


# ------------------------------------------------------------------------------------------ the publisher


def publish(rate_hz: float) -> int:
    """Publishes the direct loop's five topics at ``rate_hz`` with the stack's QoS until killed."""
    import rclpy  # noqa: PLC0415
    from rclpy.context import Context  # noqa: PLC0415
    from sensor_msgs.msg import JointState  # noqa: PLC0415
    from smm_bag.cdr import encode_float64_multi_array, encode_joint_state  # noqa: PLC0415
    from smm_msgs_py.qos import qos_for_topic  # noqa: PLC0415
    from std_msgs.msg import Float64MultiArray  # noqa: PLC0415

    from smm_msgs_py import topics  # noqa: PLC0415

    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("memory_publisher", namespace=NAMESPACE, context=context)
    names = ["alpha", "beta"]
    joint = ("joint:alpha,beta", 2, 2)
    internals = ("quantity:" + ",".join(f"q{i}" for i in range(24)), 24, 48)
    bridge = ("quantity:" + ",".join(f"b{i}" for i in range(10)), 10, 20)
    kinds = {
        topics.JOINT_STATES: JointState,
        topics.TORQUE_COMMAND: Float64MultiArray,
        topics.REFERENCE: Float64MultiArray,
        topics.CONTROLLER_INTERNALS: Float64MultiArray,
        topics.HW_BRIDGE_INTERNALS: Float64MultiArray,
    }
    publishers = {
        name: node.create_publisher(kind, name, qos_for_topic(name)) for name, kind in kinds.items()
    }
    start, first_ns = time.monotonic(), time.time_ns()
    period_ns = round(1e9 / rate_hz)
    step = 0
    while True:
        due = int((time.monotonic() - start) * rate_hz)
        for _ in range(min(due - step, 50)):  # catches up in bursts of at most 50 steps
            step += 1
            stamp = first_ns + step * period_ns  # on the period's grid: a gap is a sample dropped
            dim = (f"stamp_ns:{stamp}", 1, 1)
            value = step * 1e-6
            publishers[topics.JOINT_STATES].publish(
                encode_joint_state(stamp, names, [value, -value], [0.1, 0.2], [1.0, 2.0])
            )
            publishers[topics.TORQUE_COMMAND].publish(encode_float64_multi_array([joint, dim], [1.0, 2.0]))
            publishers[topics.REFERENCE].publish(
                encode_float64_multi_array(
                    [("order:position,velocity,acceleration", 3, 6), joint, dim], [value] * 6
                )
            )
            publishers[topics.CONTROLLER_INTERNALS].publish(
                encode_float64_multi_array([internals, joint, dim], [value] * 48)
            )
            publishers[topics.HW_BRIDGE_INTERNALS].publish(
                encode_float64_multi_array([bridge, joint, dim], [value] * 20)
            )
        time.sleep(0.001)


# ------------------------------------------------------------------------------------------- the driver


class Run:
    """The recorder in its probe, the publisher, the events; everything under ``out``."""

    def __init__(self, out: Path, arguments: argparse.Namespace) -> None:
        self.out = out
        self.arguments = arguments
        self.start = time.monotonic()
        self.start_ns = time.time_ns()
        self.recorder = self._spawn(
            [
                "--probe",
                "--sample-every",
                str(arguments.sample_every),
                *(["--tracemalloc"] if arguments.tracemalloc else []),
                "--",
                "--ros-args",
                "-r",
                f"__ns:={NAMESPACE}",
                "-p",
                f"output:={out / 'bag'}",
                "-p",
                f"max_size:={arguments.max_size}",
                "-p",
                "plant:=hardware",
                "-p",
                "clock_mode:=realtime",
                *(arg for parameter in arguments.param for arg in ("-p", parameter)),
            ],
            "recorder.log",
        )
        self.publisher = self._start_publisher()
        self._next_trim = self.start + arguments.trim_every

    def _spawn(self, argv: list[str], log: str) -> subprocess.Popen[bytes]:
        env = dict(os.environ)
        env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        if self.arguments.tracemalloc and argv[0] == "--probe":
            env["PYTHONTRACEMALLOC"] = "1"
        for item in self.arguments.env:
            key, _, value = item.partition("=")
            if argv[0] == "--probe":
                env[key] = value
        with (self.out / log).open("ab") as stream:
            return subprocess.Popen(
                [sys.executable, __file__, "--out", str(self.out), *argv],
                env=env,
                stdout=stream,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )

    def _start_publisher(self) -> subprocess.Popen[bytes]:
        return self._spawn(["--publish", "--rate", str(self.arguments.rate)], "publisher.log")

    def event(self, kind: str, seconds: float = 0.0) -> None:
        """Logs ``kind`` (lasting ``seconds``) at the run's time."""
        entry = {"t": round(time.monotonic() - self.start, 2), "event": kind, "s": seconds}
        with (self.out / EVENTS_FILE).open("a") as file:
            file.write(json.dumps(entry) + "\n")

    def respawn(self) -> None:
        """SIGKILL of the publisher, a new one started (a new participant)."""
        self.event("publisher killed and restarted")
        self.publisher.kill()
        self.publisher.wait()
        time.sleep(1.0)
        self.publisher = self._start_publisher()

    def stop(self, seconds: float) -> None:
        """Every thread of the recorder stopped for ``seconds``."""
        self.event("recorder SIGSTOP", seconds)
        os.kill(self.recorder.pid, signal.SIGSTOP)
        time.sleep(seconds)
        os.kill(self.recorder.pid, signal.SIGCONT)

    def hold(self, seconds: float) -> None:
        """The recorder's executor held in a callback for ``seconds`` (its middleware threads run on)."""
        self.event("recorder executor held", seconds)
        (self.out / HOLD_FILE).write_text(str(seconds))
        os.kill(self.recorder.pid, signal.SIGUSR1)

    def trim(self) -> None:
        """``malloc_trim(0)`` in the recorder (its figures in ``trim.txt``)."""
        self.event("malloc_trim(0) in the recorder")
        os.kill(self.recorder.pid, signal.SIGUSR2)

    def wait_until(self, seconds: float) -> None:
        """Sleeps until ``seconds`` after the start; raises if the recorder ended."""
        while time.monotonic() - self.start < seconds:
            if self.recorder.poll() is not None:
                raise RuntimeError(f"recorder_node ended with {self.recorder.returncode}: see recorder.log")
            every = self.arguments.trim_every
            if every and time.monotonic() >= self._next_trim:
                os.kill(self.recorder.pid, signal.SIGUSR2)
                self._next_trim = time.monotonic() + every
            time.sleep(0.2)

    def finish(self) -> int:
        """Stops the publisher, then the recorder (SIGINT: it closes the bag); its exit code."""
        self.publisher.kill()
        self.publisher.wait()
        os.killpg(self.recorder.pid, signal.SIGINT)
        try:
            return self.recorder.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.recorder.kill()
            return self.recorder.wait()


def schedule(arguments: argparse.Namespace) -> list[tuple[float, str, float]]:
    """``(time s, event, seconds)`` of the run: warm-up, respawns, stops, holds, quiet."""
    plan = []
    stalls = [float(value) for value in arguments.stall_seconds.split(",")]
    phases = [kind for kind in ("respawn", "stop", "hold") if kind not in arguments.skip]
    for index, kind in enumerate(phases):
        begin = arguments.warmup + index * arguments.phase
        for k, at in enumerate(range(round(begin), round(begin + arguments.phase), round(arguments.every))):
            plan.append((float(at + arguments.every / 2), kind, stalls[k % len(stalls)]))
    if arguments.trim_at_end:
        plan.append((arguments.warmup + len(phases) * arguments.phase + arguments.quiet / 2, "trim", 0.0))
    return plan


def drive(out: Path, arguments: argparse.Namespace) -> int:
    """Runs the schedule, then prints the figures."""
    plan = schedule(arguments)
    phases = [kind for kind in ("respawn", "stop", "hold") if kind not in arguments.skip]
    end = arguments.warmup + len(phases) * arguments.phase + arguments.quiet
    run = Run(out, arguments)
    try:
        for at, kind, seconds in plan:
            run.wait_until(at)
            if kind == "respawn":
                run.respawn()
            elif kind == "stop":
                run.stop(seconds)
            elif kind == "trim":
                run.trim()
            else:
                run.hold(seconds)
        run.wait_until(end)
    finally:
        code = run.finish()
    report(out, arguments, phases)
    if arguments.drops:
        drops(out / "bag", run.start_ns, round(1e9 / arguments.rate))
    if (out / TRIM_FILE).exists():
        took = sorted(float(line.split()[-2]) for line in (out / TRIM_FILE).read_text().splitlines())
        median, longest = took[len(took) // 2], took[-1]
        print(f"malloc_trim(0) {len(took)} times: median {median:.1f} ms, max {longest:.1f} ms")
    for line in (out / "recorder.log").read_text().splitlines():  # its loss report: drops are stamp gaps
        if f"{NAMESPACE}/" in line and "received" in line:
            print(line.split("]: ", 1)[-1])
    print(f"recorder exit {code}; bag, samples and logs in {out}")
    return 0 if code == 0 else 1


def _mib(kib: float) -> str:
    return f"{kib / 1024:6.1f}"


def _in_use(entry: dict[str, Any]) -> int:
    return sum(system - free for system, free in entry["arenas"])


def _grown(before: dict[str, Any], after: dict[str, Any]) -> str:
    """The mappings whose RSS changed by 256 KiB or more: ``[heap]`` and anonymous ones by address."""
    changes = {"[heap]": after["heap_rss"] - before["heap_rss"]}
    for address in {*before["anon"], *after["anon"]}:
        changes[address] = after["anon"].get(address, 0) - before["anon"].get(address, 0)
    return ", ".join(f"{name} {kib / 1024:+.1f}" for name, kib in sorted(changes.items()) if abs(kib) >= 256)


def report(out: Path, arguments: argparse.Namespace, phases: Sequence[str]) -> None:
    """The RSS curve with the events, then the growth per phase."""
    samples = [json.loads(line) for line in (out / SAMPLES_FILE).read_text().splitlines() if line.strip()]
    events_path = out / EVENTS_FILE
    events = (
        [json.loads(line) for line in events_path.read_text().splitlines()] if events_path.exists() else []
    )
    print(
        "    t s |  RSS  anon  file   shm maps (MiB) | main arena sys  use | other arenas sys  use  n | "
        "py blocks traced MiB | threads | events since the sample before"
    )
    last = -1.0
    for entry in samples:
        arenas = entry["arenas"] or [(0, 0)]
        main_sys, main_free = arenas[0]
        rest_sys = sum(system for system, _ in arenas[1:])
        rest_free = sum(free for _, free in arenas[1:])
        traced = "" if entry["traced"] is None else f"{entry['traced'] / 2**20:.1f}"
        happened = "; ".join(
            e["event"] + (f" {e['s']:g} s" if e["s"] else "") for e in events if last < e["t"] <= entry["t"]
        )
        last = entry["t"]
        print(
            f"{entry['t']:7.0f} |{_mib(entry['VmRSS'])}{_mib(entry['RssAnon'])}{_mib(entry['RssFile'])}"
            f"{_mib(entry['RssShmem'])} {entry['shm_maps']:4d}       |         {main_sys / 2**20:6.1f}"
            f" {(main_sys - main_free) / 2**20:5.1f} |           {rest_sys / 2**20:6.1f}"
            f" {(rest_sys - rest_free) / 2**20:5.1f} {len(arenas) - 1:2d} | {entry['py_blocks']:9d} "
            f"{traced:>10s} | {entry['Threads']:7d} | {happened}"
        )
    bounds = [0.0, arguments.warmup]
    for _ in phases:
        bounds.append(bounds[-1] + arguments.phase)
    bounds.append(bounds[-1] + arguments.quiet)
    print("growth per phase (its last sample - the last sample before it), MiB:")
    for name, begin, finish in zip(["warm-up", *phases, "quiet"], bounds, bounds[1:], strict=False):
        before = [entry for entry in samples if entry["t"] <= begin] or samples[:1]
        inside = [entry for entry in samples if begin < entry["t"] <= finish]
        if not inside:
            continue
        a, b = before[-1], inside[-1]
        print(
            f"  {name:8s} {begin:4.0f}-{finish:4.0f} s: RSS {(b['VmRSS'] - a['VmRSS']) / 1024:+.1f} (anon "
            f"{(b['RssAnon'] - a['RssAnon']) / 1024:+.1f}, shm {(b['RssShmem'] - a['RssShmem']) / 1024:+.1f} "
            f"in {b['shm_maps'] - a['shm_maps']:+d} maps), malloc in use "
            f"{(_in_use(b) - _in_use(a)) / 2**20:+.1f}, by mapping: {_grown(a, b) or '-'}"
        )


def drops(bag: Path, start_ns: int, period_ns: int) -> None:
    """The ``joint_states`` samples missing in the bag's stamps, by the run's time (s) they were noticed."""
    from smm_bag.cdr import stamp_of  # noqa: PLC0415
    from smm_bag.reader import BagReader  # noqa: PLC0415

    topic = f"{NAMESPACE}/joint_states"
    previous: int | None = None
    found: list[tuple[float, int]] = []
    with BagReader(bag) as reader:
        for _, log_time_ns, data in reader.raw_messages([topic]):
            stamp = stamp_of("sensor_msgs/msg/JointState", data)
            if stamp is None:
                continue
            if previous is not None and stamp - previous > period_ns and stamp - previous < 60 * 10**9:
                found.append(((log_time_ns - start_ns) / 1e9, round((stamp - previous) / period_ns) - 1))
            previous = stamp
    windows: dict[int, int] = {}
    for seconds, missing in found:
        windows[int(seconds // 10) * 10] = windows.get(int(seconds // 10) * 10, 0) + missing
    print(f"{topic}: {sum(n for _, n in found)} samples missing in {len(found)} gaps; per 10 s of the run:")
    print("  " + ", ".join(f"{start}-{start + 10} s: {n}" for start, n in sorted(windows.items())))


def build_parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out", type=Path, help="new folder: samples, events, logs, the bag (default: temporary)"
    )
    parser.add_argument("--rate", type=float, default=1000.0, help="steps per second of the five topics")
    parser.add_argument("--warmup", type=float, default=90.0, help="seconds before the first phase")
    parser.add_argument("--phase", type=float, default=120.0, help="seconds of each phase")
    parser.add_argument("--every", type=float, default=30.0, help="seconds between two events of a phase")
    parser.add_argument("--quiet", type=float, default=60.0, help="seconds of the last, quiet phase")
    parser.add_argument("--skip", action="append", default=[], choices=("respawn", "stop", "hold"))
    parser.add_argument(
        "--stall-seconds", default="1,2,3", help="lengths of the stops and holds in turn (s, comma-separated)"
    )
    parser.add_argument(
        "--trim-every", type=float, default=0.0, help="malloc_trim(0) in the recorder every S s (0: never)"
    )
    parser.add_argument("--trim-at-end", action="store_true", help="malloc_trim(0) in the quiet phase")
    parser.add_argument("--sample-every", type=float, default=3.0, help="sampling period (s)")
    parser.add_argument("--max-size", type=int, default=256 * 2**20, help="the recorder's split size (bytes)")
    parser.add_argument(
        "--param", action="append", default=[], metavar="NAME:=VALUE", help="recorder parameter"
    )
    parser.add_argument(
        "--env", action="append", default=[], metavar="KEY=VALUE", help="recorder environment"
    )
    parser.add_argument("--tracemalloc", action="store_true", help="also trace Python's heap (slower)")
    parser.add_argument("--drops", action="store_true", help="read the bag: joint_states samples missing")
    parser.add_argument("--keep-bag", action="store_true", help="keep the bag (else deleted at the end)")
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--probe", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--publish", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("rest", nargs="*", help=argparse.SUPPRESS)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: re-executes itself in a private network namespace, then drives the run."""
    raw = list(sys.argv[1:] if argv is None else argv)
    arguments = build_parser().parse_args(raw)
    if arguments.probe:
        return probe(arguments.out, arguments.sample_every, arguments.rest)
    if arguments.publish:
        return publish(arguments.rate)
    if not arguments.inner:
        sys.path.insert(0, str(HERE.parent / "bench"))
        from bench_graph import reexec_in_private_netns  # noqa: PLC0415

        return int(reexec_in_private_netns(raw, __file__, domain_base=150, domains=10))
    out = arguments.out or Path(tempfile.mkdtemp(prefix="recorder_memory_"))
    out.mkdir(parents=True, exist_ok=True)
    print(
        f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; ROS_DOMAIN_ID "
        f"{os.environ.get('ROS_DOMAIN_ID')}; recorder env {arguments.env or 'as ours'}",
        flush=True,
    )
    code = drive(out, arguments)
    if not arguments.keep_bag:
        for file in (out / "bag").glob("*.mcap"):
            file.unlink()
    return code


if __name__ == "__main__":
    sys.exit(main())
