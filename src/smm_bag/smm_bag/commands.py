"""The storage and replay commands of ``smm-bag``: each takes parsed options, prints, returns an exit code.

Exit codes: ``smm_bag.exit_codes``.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Literal, TextIO

from smm_bag.convert import convert_bag
from smm_bag.errors import BagError
from smm_bag.exit_codes import EXIT_CHECK_FAILED, EXIT_OK, exit_code
from smm_bag.exit_codes import fail as _fail
from smm_bag.info import format_info
from smm_bag.lockstep import LockstepOptions, LockstepResult, play_lockstep
from smm_bag.player import PlayOptions, PlayResult, play
from smm_bag.progress import Progress
from smm_bag.repair import repair_bag
from smm_bag.repair_report import format_repair

__all__ = ["convert", "info", "play_command", "repair"]


def info(bag: Path, stdout: TextIO | None = None, stderr: TextIO | None = None) -> int:
    """``smm-bag info BAG``."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        out.write(format_info(bag) + "\n")
    except BagError as error:
        return _fail(error, err)
    return EXIT_OK


def convert(
    bag: Path,
    output: Path,
    *,
    compression: Literal["none", "zstd"] = "none",
    stdout: TextIO | None = None,
    stderr: TextIO | None = None,
) -> int:
    """``smm-bag convert BAG OUTPUT``: the bag (sqlite3 or MCAP) written as a new MCAP bag."""
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        result = convert_bag(
            bag, output, compression=compression, progress=Progress(f"converting {bag.name}", 1, err)
        )
    except BagError as error:
        return _fail(error, err)
    out.write(
        f"{output}: {result.messages} messages on {result.topics} topics, from {result.source_storage} "
        "to mcap\n"
    )
    if result.undefined_types:
        err.write(
            "smm-bag: warning: no message definition stored or installed for "
            f"{', '.join(result.undefined_types)}: stored without one, as rosbag2 does\n"
        )
    return EXIT_OK


def repair(
    bag: Path, *, backup: bool = True, stdout: TextIO | None = None, stderr: TextIO | None = None
) -> int:
    """``smm-bag repair BAG``: rebuild damaged files and metadata.yaml; prints per file what was lost.

    Exit 0 when every file is intact or repaired, 8 when nothing could be saved of a file (left as it was).
    """
    out, err = stdout or sys.stdout, stderr or sys.stderr
    try:
        report = repair_bag(bag, backup=backup, progress=lambda name: print(f"checking {name}", file=err))
    except BagError as error:
        return _fail(error, err)
    out.write(format_repair(report) + "\n")
    for failure in report.errors:
        err.write(f"smm-bag: error: {failure}\n")
    return exit_code(report.errors[0]) if report.errors else EXIT_OK


def play_command(
    bag: Path,
    options: PlayOptions | LockstepOptions,
    ros_args: Sequence[str] = (),
    stderr: TextIO | None = None,
) -> int:
    """``smm-bag play BAG [--lockstep]``: publish the bag until its end (or SIGINT/SIGTERM when looping).

    Lockstep: exits 1 when an answer timed out.
    """
    import signal  # noqa: PLC0415

    import rclpy  # noqa: PLC0415
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
    from rclpy.signals import SignalHandlerOptions  # noqa: PLC0415

    from smm_node_runtime import ensure_localhost_discovery  # noqa: PLC0415

    err = stderr or sys.stderr
    ensure_localhost_discovery()
    stop = {"requested": False}

    def request_stop(_signum: int, _frame: object) -> None:
        stop["requested"] = True

    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    context = rclpy.Context()  # type: ignore[attr-defined]
    rclpy.init(args=["smm-bag", *ros_args], context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("smm_bag_player", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    result: PlayResult | LockstepResult
    try:
        progress = Progress(f"playing {bag.name}", 1, err)
        if isinstance(options, LockstepOptions):
            result = play_lockstep(
                bag, node, executor, options, should_stop=lambda: stop["requested"], progress=progress
            )
        else:
            result = play(
                bag,
                node,
                options,
                should_stop=lambda: stop["requested"],
                progress=progress,
                warn=lambda text: print(f"smm-bag: warning: {text}", file=err),
            )
    except BagError as error:
        return _fail(error, err)
    finally:
        executor.shutdown()
        node.destroy_node()  # type: ignore[no-untyped-call]
        context.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    for topic, count in result.published.items():
        err.write(f"{topic}: {count} messages published\n")
    if isinstance(result, PlayResult) and result.skipped:
        err.write(f"{len(result.skipped)} topics skipped: {', '.join(result.skipped)}\n")
    if isinstance(result, LockstepResult):
        answered = sum(stamp in result.answers for stamp in result.stamps)
        err.write(
            f"{len(result.stamps)} stamps played, {answered} answered, {len(result.timeouts)} timed out\n"
        )
        if result.timeouts:
            shown = ", ".join(str(stamp) for stamp in result.timeouts[:5])
            err.write(f"smm-bag: no answer within the timeout for stamps (ns) {shown}\n")
            return EXIT_CHECK_FAILED
    return EXIT_OK
