"""The independent CANopen bench in real time beside the emulated one: tracking RMS and their ratio.

Figures, not pass/fail (``make bench``); every process in a private network namespace (as bench_hil.py).
Back to back, the same scenario (case 2) and live duration, at the default CANopen rate (200 Hz) unless
``--control-rate``:

1. tests/hw_bridge/independent_bench/run.py (``--keep-answering``, ``--clock``; under SCHED_FIFO at the
   emulator's priority where allowed: it stands for hardware) beside ``smm-launch --plant
   hardware --link canopen --board external --clock-mode realtime --scenario case2 --params-file bench.yaml
   --record --duration D``, which the bridge ends itself after D s live (``verdict.ends_run``), judged: exit 0
   when it controlled;
2. ``smm-launch --plant hardware --link canopen --clock-mode realtime --scenario case2 --duration D
   --record``.

Tracking RMS over the first D s of each bag (``smm-bag analyze --start 0 --end D``), and the ratio
independent / emulated (the acceptance of issue 43: at most 1.1x).
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

from canopen_runs import Run, finish, launch, start, tracking_rms, uptime, workdir  # noqa: E402
from hw_bridge.independent_bench import parameters  # type: ignore[import-not-found]  # noqa: E402

GROUP, PORT = "239.74.163.17", 43151
"""The independent bench's udp_multicast bus (loopback of this private namespace)."""
INDEPENDENT_FIGURES = "independent bench: {"


def build_parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=20.0, help="live seconds per run (default 20)")
    parser.add_argument("--clock", choices=("sync", "wall", "both"), default="sync", help="the bench's clock")
    parser.add_argument("--control-rate", default=None, help="Hz (default: smm-launch's for CANopen)")
    parser.add_argument("--force", action="store_true", help="arm whatever the preflight measured")
    parser.add_argument("--repeat", type=int, default=1, help="pairs of runs (default 1)")
    parser.add_argument("--keep", type=Path, default=None, help="keep the logs and bags in this folder")
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    return parser


def _common(arguments: argparse.Namespace, bag: Path) -> list[str]:
    options = ["--clock-mode", "realtime", "--scenario", "case2", "--record", str(bag)]
    if arguments.control_rate is not None:
        options += ["--control-rate", str(arguments.control_rate)]
    return options + (["--force"] if arguments.force else [])


def independent_run(work: Path, arguments: argparse.Namespace, clock: str, tag: str) -> tuple[Run, str]:
    """Run 1 of the module docstring; the run and the bench's own closing figures."""
    status = work / f"independent_{tag}.json"
    params = parameters.bench_parameters(work / "bench.yaml", GROUP, PORT)
    bench_log = work / f"independent_bench_{tag}.log"
    command = [sys.executable, str(parameters.HERE / "run.py"), GROUP, str(PORT), str(arguments.duration)]
    bench = start([*command, str(status), "--keep-answering", "--clock", clock], bench_log, board=True)
    options = ["--board", "external", "--params-file", str(params), *_common(arguments, work / f"i_{tag}")]
    options += ["--duration", str(arguments.duration)]  # the bridge ends an external bench's run itself
    try:
        run = launch(
            f"independent bench ({clock} clock)",
            options,
            work / f"launch_independent_{tag}.log",
            timeout_s=arguments.duration + 600.0,
        )
    finally:
        bench.send_signal(signal.SIGTERM)
        bench_run = finish(bench, bench_log, "bench", time.monotonic(), 30.0)
    said = [line for line in bench_run.lines if line.startswith(INDEPENDENT_FIGURES)]
    figures = said[-1].removeprefix("independent bench: ") if said else "(no closing figures)"
    if not status.exists():
        figures += f"; its duration was never reached (bench exit {bench_run.code})"
    return run, figures


def describe(run: Run) -> str:
    """Exit code, the bridge's late periods and verdict, receive -> send, the emulator's figures."""
    parts = [f"exit {run.code}"]
    host = run.host
    if host is None:
        parts.append(f"no host: line ({run.why()})")
    else:
        parts.append(f"host late {host[1]} of {host[2]} periods of {host[3]} ms ({host[4]} %), {host[5]}")
    if run.receive_send is not None:
        parts.append("receive->send p50 / p99 / max {} / {} / {} us".format(*run.receive_send))
    parts.append(f"preflight {run.preflight}")
    emulator: dict[str, Any] | None = run.emulator
    if emulator is not None:
        parts.append(
            f"emulator: held {emulator['late_commands']} of {emulator['enabled_ticks']} ACTIVE SYNCs, "
            f"{emulator.get('skipped_periods', '-')} periods skipped, feedback->command p50 / p99 / max "
            f"{_us(emulator['latency_p50_us'])} / {_us(emulator['latency_p99_us'])} / "
            f"{_us(emulator.get('latency_max_us'))} us"
        )
    if any("did not stop cleanly" in line or "did not control" in line for line in run.lines):
        parts.append("NOTE: " + run.why(2))
    return "; ".join(parts)


def _us(value: float | None) -> str:
    return "-" if value is None else f"{value:.0f}"


def _rms_text(rms: tuple[float, float] | str) -> str:
    return rms if isinstance(rms, str) else f"{1e3 * rms[0]:.2f} / {1e3 * rms[1]:.2f} mrad"


def pair(work: Path, arguments: argparse.Namespace, clock: str, tag: str) -> None:
    """One independent run and one emulated run, back to back; prints both and the ratio."""
    independent, figures = independent_run(work, arguments, clock, tag)
    print(f"  {describe(independent)} ({independent.wall_s:.0f} s)", flush=True)
    print(f"  independent bench's own figures: {figures}", flush=True)
    options = [*_common(arguments, work / f"e_{tag}"), "--duration", str(arguments.duration)]
    emulated = launch("emulated bench", options, work / f"launch_emulated_{tag}.log")
    print(f"  {describe(emulated)} ({emulated.wall_s:.0f} s)", flush=True)
    mine = tracking_rms(work / f"i_{tag}", arguments.duration)
    theirs = tracking_rms(work / f"e_{tag}", arguments.duration)
    print(f"  tracking RMS alpha / beta over [0, {arguments.duration:g}) s: independent {_rms_text(mine)}, "
          f"emulated {_rms_text(theirs)}", flush=True)  # fmt: skip
    if not isinstance(mine, str) and not isinstance(theirs, str):
        ratio = [a / b for a, b in zip(mine, theirs, strict=True)]
        print(
            f"  ratio independent / emulated: {ratio[0]:.3f}x / {ratio[1]:.3f}x (target <= 1.1x)", flush=True
        )


def main(argv: list[str]) -> int:
    arguments = build_parser().parse_args(argv)
    if not arguments.inner:
        from bench_graph import reexec_in_private_netns

        return reexec_in_private_netns(argv, __file__, domain_base=140, domains=10)
    print(f"uptime before: {uptime()}", flush=True)
    clocks = ("sync", "wall") if arguments.clock == "both" else (arguments.clock,)
    with workdir(arguments.keep, "bench_independent_") as work:
        for repeat in range(arguments.repeat):
            for clock in clocks:
                print(
                    f"\n--- pair {repeat + 1} of {arguments.repeat}, the bench's clock {clock} ---",
                    flush=True,
                )
                pair(work, arguments, clock, f"{repeat}_{clock}")
    print(f"uptime after: {uptime()}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
