"""The CANopen link's SYNC rates in real time on the emulated bus: missed cycles, receive -> send, tracking.

Figures, not pass/fail (``make bench``); every process in a private network namespace (as bench_hil.py).
For each rate R (``--rates``, default 100, 200, 250, 500, 1000 Hz), back to back:

1. lockstep: ``smm-launch --plant hardware --link canopen --clock-mode lockstep --control-rate R
   --scenario S --duration D --record``: the tracking RMS to compare with;
2. real time, idle: the same with ``--clock-mode realtime --force`` (``--force``: every rate arms and gives
   figures; the preflight's own verdict, "holds" or "would refuse", is in the table);
3. real time beside ``--busy`` busy processes (``tools/under_load.py --busy N``; 0 skips it).

Per real-time run: the bridge's closing ``host:`` line (late periods: the answer written after the next
SYNC was due, or a SYNC slot skipped; receive -> send p50 / p99 / max of the direct loop), the emulator's
status (SYNCs with both valves ACTIVE at which a valve held its setpoint, the periods skipped, its feedback
-> command p50 / p99 / max: SYNC to the later valve's RPDO), the tracking RMS over [``--skip``, D) s of the
bag (``smm-bag analyze``) and its ratio to lockstep. A rate that cannot run (a bus-load refusal, a crash)
gets its reason in the table. Prints a markdown table. Defaults: one full pass in about 6 minutes here.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from canopen_runs import FLOOR, UNDER_LOAD, Run, launch, tracking_rms, uptime, workdir  # noqa: E402

RATES_HZ = (100, 200, 250, 500, 1000)


def build_parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", default=",".join(map(str, RATES_HZ)), help="Hz, comma-separated")
    parser.add_argument("--duration", type=float, default=6.0, help="live seconds per run (default 6)")
    parser.add_argument("--scenario", default="case1", help="smm-launch --scenario (default case1)")
    parser.add_argument("--skip", type=float, default=1.0, help="RMS from this many s on (default 1)")
    parser.add_argument("--busy", type=int, default=2, help="busy processes of the loaded run (0: none)")
    parser.add_argument("--keep", type=Path, default=None, help="keep the logs and bags in this folder")
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    return parser


def _us(value: float | None) -> str:
    return "-" if value is None else f"{value:.0f}"


def _mrad(rms: tuple[float, float] | str) -> str:
    return "-" if isinstance(rms, str) else f"{1e3 * rms[0]:.2f} / {1e3 * rms[1]:.2f}"


def row(
    rate: int, load: str, run: Run, rms: tuple[float, float] | str, lockstep: tuple[float, float] | str
) -> str:
    """One line of the table (a run that gave no closing line: its reason)."""
    host = run.host
    if host is None:
        return f"| {rate} | {load} | {run.code} | {run.preflight} | did not run: {run.why()} |||||||"
    late = f"{host[1]} of {host[2]} ({host[4]} %)"
    verdict = host[5]
    if verdict != "controlled":
        verdict = "faulted" if "faulted" in verdict else "late" if "late or not live" in verdict else verdict
    receive_send = "-" if run.receive_send is None else " / ".join(map(str, run.receive_send))
    emulator: dict[str, Any] = run.emulator or {}
    held = f"{emulator.get('late_commands', '-')} of {emulator.get('enabled_ticks', '-')}"
    skipped = str(emulator.get("skipped_periods", "-"))
    answer = " / ".join(
        _us(emulator.get(key)) for key in ("latency_p50_us", "latency_p99_us", "latency_max_us")
    )
    ratio = "-"
    if not isinstance(rms, str) and not isinstance(lockstep, str):
        ratio = f"{rms[0] / lockstep[0]:.2f}x / {rms[1] / lockstep[1]:.2f}x"
    floor = run.first(FLOOR)
    load_text = load if floor is None else f"{load} (1 ms sleep overshoot p99 {floor[1]} us)"
    cells = [
        str(rate),
        load_text,
        f"{run.code} ({verdict})",
        run.preflight,
        late,
        skipped,
        held,
        receive_send,
    ]
    return "| " + " | ".join([*cells, answer, _mrad(rms), ratio]) + " |"


def main(argv: list[str]) -> int:
    arguments = build_parser().parse_args(argv)
    if not arguments.inner:
        from bench_graph import reexec_in_private_netns

        return reexec_in_private_netns(argv, __file__, domain_base=150, domains=10)
    rates = [int(text) for text in arguments.rates.split(",")]
    duration = arguments.duration
    print(f"uptime before: {uptime()}", flush=True)
    loads: list[tuple[str, tuple[str, ...]]] = [("idle", ())]
    if arguments.busy:
        loads.append((f"{arguments.busy} busy", (*UNDER_LOAD, "--busy", str(arguments.busy), "--")))
    rows: list[str] = []
    lockstep_rows: list[str] = []
    with workdir(arguments.keep, "bench_canopen_rates_") as work:
        for rate in rates:
            common = [
                "--control-rate",
                str(rate),
                "--scenario",
                arguments.scenario,
                "--duration",
                str(duration),
            ]
            bag = work / f"lockstep_{rate}"
            reference = launch(
                "lockstep", ["--clock-mode", "lockstep", *common, "--record", str(bag)], work / f"l{rate}.log"
            )
            lockstep = (
                tracking_rms(bag, duration, arguments.skip)
                if reference.code == 0
                else f"exit {reference.code}: {reference.why()}"
            )
            lockstep_rows.append(
                f"| {rate} | {reference.code} | {_mrad(lockstep)} | {reference.wall_s:.0f} s |"
            )
            if isinstance(lockstep, str):
                print(f"  lockstep at {rate} Hz: {lockstep}", flush=True)
            for load, prefix in loads:
                bag = work / f"realtime_{rate}_{len(prefix)}"
                options = ["--clock-mode", "realtime", *common, "--force", "--record", str(bag)]
                run = launch(load, options, work / f"r{rate}_{len(prefix)}.log", prefix=prefix)
                rms = tracking_rms(bag, duration, arguments.skip) if run.host is not None else "no run"
                rows.append(row(rate, load, run, rms, lockstep))
                print(f"  {rows[-1]}  ({run.wall_s:.0f} s)", flush=True)
    print(f"\nuptime after: {uptime()}")
    print(
        f"\n{arguments.scenario}, {duration:g} s live a run, RMS over [{arguments.skip:g}, {duration:g}) s, "
        "every real-time run with --force:\n"
    )
    print(
        "| rate (Hz) | load | exit | preflight | host late periods | periods skipped | emulator held "
        "(of ACTIVE SYNCs) | host receive -> send p50 / p99 / max (us) | emulator feedback -> command "
        "p50 / p99 / max (us) | RMS alpha / beta (mrad) | vs lockstep |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print("\n| rate (Hz) | lockstep exit | lockstep RMS alpha / beta (mrad) | wall time |\n|---|---|---|---|")
    print("\n".join(lockstep_rows))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
