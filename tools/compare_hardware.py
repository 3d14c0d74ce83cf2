"""The hardware half of tools/compare_baseline.py: lockstep ``--plant hardware`` runs, frames and topics.

Each tree's own ``smm-launch --plant hardware --clock-mode lockstep --loop L --record`` runs, with one part
swapped: the emulator process is this file's :func:`drive` (this tree's ``BoardCore`` and configuration
parsing, the same for both trees), found first through ``AMENT_PREFIX_PATH``. It ticks the board on each
enabled answer, as the emulator's lockstep does, logs every feedback frame it sends and every command frame it
receives, in order, and plays a script by board tick: an e-stop latched on the board (its e-stop button),
and, once the bridge saw it, a re-arm through the bridge's ``~/rearm`` service. The board waits for no
clock, so the frames and topics depend on the inputs alone; two trees compare bit for bit. Before comparing,
sessions (random per boot and per configure) are set to 1 and command sequence numbers are counted from the
first enabled command: before the output goes live the bridge answers a re-sent feedback again, and whether
the driver re-sends depends on when DDS matched the controller; those safe frames are counted, not compared.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from smm_bench_emulator.board import BoardCore
from smm_bench_emulator.cli import build_parser, config_from_args, from_ros_arguments
from smm_hw_bridge.protocol import (
    CommandFlag,
    CommandFrame,
    ProtocolError,
    decode_command,
    decode_feedback,
    encode,
)
from smm_hw_bridge.transport import UdpTransport
from std_srvs.srv import Trigger

HERE = Path(__file__).resolve().parents[1]
INPUTS = {"case1": ("case1", 0), "case2": ("case2", 0), "estop": ("case2", 2000)}
"""Input name -> (scenario, board tick of the scripted e-stop, 0: none)."""
LOOPS = ("topics", "direct")
EMULATOR = "smm_bench_emulator"
BOOT_RESEND_S = 0.5
"""Before a host locks on, the boot feedback is re-sent this often (the bridge binds at configure)."""
STALL_RESEND_S = 5.0
"""An unanswered feedback is re-sent after this long (a lost sample; the comparison then shows it)."""


def private_netns(command: list[str]) -> list[str]:
    """``command`` in a fresh network namespace with only ``lo`` up (tests/netns_exec.py)."""
    unshare = ["unshare", "--net"] + ([] if os.geteuid() == 0 else ["--map-root-user"])
    return [*unshare, "--", sys.executable, str(HERE / "tests" / "netns_exec.py"), *command]


def _estop_frame(board: Any) -> bytes:
    """A command frame carrying ESTOP, as the board's e-stop button latches it (honoured from any sender)."""
    return encode(CommandFrame(1, 1, board.session, 0, 0, int(CommandFlag.ESTOP), 0, (0, 0)))


def _rearm(done: threading.Event, log: list[str]) -> None:
    """Calls ``/smm/hw_bridge_node/rearm`` (std_srvs/Trigger) once; notes the answer."""
    context = Context()
    rclpy.init(args=[], context=context)  # not this process's --ros-args (the emulator's options)
    node = rclpy.create_node("compare_rearm", context=context)
    try:
        client = node.create_client(Trigger, "/smm/hw_bridge_node/rearm")
        if not client.wait_for_service(timeout_sec=30.0):
            log.append("rearm: no service")
            return
        future = client.call_async(Trigger.Request())
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executor.spin_until_future_complete(future, timeout_sec=30.0)
        result = future.result()  # type: ignore[no-untyped-call]
        log.append(f"rearm: {None if result is None else (result.success, result.message)}")
    finally:
        node.destroy_node()  # type: ignore[no-untyped-call]
        rclpy.shutdown(context=context)
        done.set()


def drive(argv: list[str]) -> int:
    """The emulator's stand-in (its ``--ros-args``): lockstep board, frame log, the scripted e-stop."""
    args = build_parser().parse_args(from_ros_arguments(argv))
    config = config_from_args(args)
    board = BoardCore(config.board)
    transport = UdpTransport(config.bind, config.host)
    estop_tick = int(os.environ.get("SMM_COMPARE_ESTOP_TICK") or 0)
    frames: dict[str, Any] = {"feedback": [], "command": [], "resends": 0, "notes": []}
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())

    def send(frame: bytes) -> None:
        frames["feedback"].append(frame.hex())
        transport.send(frame)

    send(board.start())
    sent, ticks, phase = time.monotonic(), 0, "normal"
    rearmed = threading.Event()
    rearm_thread: threading.Thread | None = None
    while not stop.is_set() and ticks < config.duration_ticks:
        data = transport.receive(0.05)
        now = time.monotonic()
        if data is None:
            waited, last = now - sent, board.last_feedback
            wait = BOOT_RESEND_S if not board.host_session else STALL_RESEND_S
            if phase != "latched" and last is not None and waited > wait:
                transport.send(encode(last))
                frames["resends"] += board.host_session != 0
                sent = now
            continue
        frames["command"].append(data.hex())
        board.receive(data)
        try:
            rearm = bool(decode_command(data).flags & CommandFlag.REARM)
        except ProtocolError:
            rearm = False
        if phase == "latched" and rearm_thread is None:  # the bridge answered the latched feedback
            rearm_thread = threading.Thread(target=_rearm, args=(rearmed, frames["notes"]), daemon=True)
            rearm_thread.start()
        ready = {
            "normal": board.answered_enabled,
            "latching": board.answered,  # the answer to the last feedback before the latch
            "latched": board.answered and rearm,  # waits for the bridge's re-arm
            "rearmed": board.answered,  # the bridge re-arms on the next feedback, answering it safe
        }[phase]
        if not ready:
            continue
        send(board.tick_lockstep())
        sent, ticks = now, ticks + 1
        if phase == "normal" and estop_tick and ticks == estop_tick:
            board.receive(_estop_frame(board))
            phase = "latching"
            frames["notes"].append(f"e-stop latched after tick {board.tick}")
        else:
            phase = {"normal": "normal", "latching": "latched", "latched": "rearmed", "rearmed": "normal"}[
                phase
            ]
    frames["ticks"] = ticks
    Path(os.environ["SMM_COMPARE_FRAMES"]).write_text(json.dumps(frames))
    if args.status_file:
        status = {"figures": f"compare driver, {ticks} ticks", "verdict": None, "late_commands": 0}
        status |= {"enabled_ticks": board.enabled_ticks, "latency_p50_us": None, "latency_p99_us": None}
        Path(args.status_file).write_text(json.dumps(status))
    transport.close()
    print(f"compare driver: {ticks} ticks, {frames['resends']} resends, {frames['notes']}", flush=True)
    return 0


def _prefix(out: Path) -> Path:
    """An ament prefix whose ``smm_bench_emulator`` executable is :func:`drive` in this tree."""
    prefix = out / "prefix"
    marker = prefix / "share" / "ament_index" / "resource_index" / "packages" / EMULATOR
    marker.parent.mkdir(parents=True, exist_ok=True)
    marker.write_text("")
    script = prefix / "lib" / EMULATOR / EMULATOR
    script.parent.mkdir(parents=True, exist_ok=True)
    script.write_text(
        f"#!{HERE / '.venv' / 'bin' / 'python'}\nimport sys\nsys.path.insert(0, {str(HERE / 'tools')!r})\n"
        "from compare_hardware import drive\nsys.exit(drive(sys.argv[1:]))\n"
    )
    script.chmod(0o755)
    return prefix


def hardware_run(
    tree: Path, out: Path, *, loop: str, name: str, seed: int, domain_id: int
) -> tuple[Path, Path]:
    """Records one lockstep hardware run of ``tree``'s graph: (bag folder, frame log)."""
    scenario, estop_tick = INPUTS[name]
    run_dir = out / f"{loop}-{name}"
    bag, frames = run_dir / "bag", run_dir / "frames.json"
    if bag.exists():
        shutil.rmtree(bag)
    run_dir.mkdir(parents=True, exist_ok=True)
    prefix = _prefix(out)
    env = {
        **os.environ,
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_DOMAIN_ID": str(domain_id),
        "AMENT_PREFIX_PATH": os.pathsep.join(
            p for p in (str(prefix), os.environ.get("AMENT_PREFIX_PATH")) if p
        ),
        "SMM_COMPARE_FRAMES": str(frames),
        "SMM_COMPARE_ESTOP_TICK": str(estop_tick),
    }
    python = str(tree / ".venv" / "bin" / "python")
    launch = [python, "-m", "smm_bringup.launcher", "--plant", "hardware", "--clock-mode", "lockstep"]
    launch += ["--loop", loop, "--scenario", scenario, "--seed", str(seed), "--record", str(bag)]
    print("+", " ".join(launch), f"(e-stop at tick {estop_tick})" if estop_tick else "", flush=True)
    code = subprocess.run(private_netns(launch), env=env, cwd=tree, check=False).returncode
    print(f"  smm-launch exit {code}", flush=True)
    return bag, frames


_U32 = 0xFFFFFFFF


def _first_enabled(commands: list[CommandFrame]) -> int:
    """Index of the first enabled command (the output going live), len() if none."""
    return next((index for index, command in enumerate(commands) if command.enabled), len(commands))


def normalised(log: dict[str, Any]) -> tuple[list[bytes], list[bytes], int]:
    """A run's frames as compared: (feedback, commands from the output going live on, commands before).

    Sessions are set to 1 (random per boot and per configure) and command sequence numbers counted from the
    first enabled command (the bridge answers a re-sent feedback again before the output goes live: how
    often depends on when DDS matched the controller, so the safe frames before live are counted only).
    """
    commands = [decode_command(bytes.fromhex(frame)) for frame in log["command"]]
    live = _first_enabled(commands)
    base = commands[live].seq if live < len(commands) else 0
    feedback = []
    for frame in log["feedback"]:
        item = decode_feedback(bytes.fromhex(frame))
        applied = (item.applied_seq - base) & _U32 if item.applied_seq else 0
        host = 1 if item.host_session else 0
        feedback.append(encode(dataclasses.replace(item, session=1, host_session=host, applied_seq=applied)))
    after = [
        encode(dataclasses.replace(command, session=1, board_session=1, seq=(command.seq - base) & _U32))
        for command in commands[live:]
    ]
    return feedback, after, live


def compare_frames(before: Path, after: Path) -> list[str]:
    """Differences between two frame logs, frame by frame in order (empty: equal)."""
    old, new = json.loads(before.read_text()), json.loads(after.read_text())
    (feedback_a, commands_a, safe_a), (feedback_b, commands_b, safe_b) = normalised(old), normalised(new)
    problems = []
    for kind, a, b in (("feedback", feedback_a, feedback_b), ("command (from live)", commands_a, commands_b)):
        first = next((index for index, (x, y) in enumerate(zip(a, b, strict=False)) if x != y), None)
        equal = first is None and len(a) == len(b)
        where = "" if first is None else f" (first at {first})"
        print(f"  {kind} frames: {len(a)} before, {len(b)} after: {'equal' if equal else 'DIFFER'}{where}")
        if not equal:
            problems.append(f"{kind} frames differ")
    print(f"  safe command frames before the output went live: {safe_a} before, {safe_b} after")
    for name, log in (("before", old), ("after", new)):
        print(f"  {name}: {log['ticks']} ticks, {log['resends']} feedback re-sent after lock, {log['notes']}")
    return problems
