"""The faults of the soak (tools/soak.py) and their criteria: emulator control port, ROS services, signals.

Each fault returns a :class:`FaultResult`; criteria and their limits: docs/SOAK.md.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import signal
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import rclpy
from lifecycle_msgs.msg import State, Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Trigger

VALIDITY_TICKS = 10
"""The bridge's default ``validity_ticks``: commands apply at most this many ticks after their measurement."""
RAMP_TICKS = 1
"""The board's default ramp to null past validity (ticks)."""
RECOVERY_LIMIT_S = 5.0
"""Re-armed and tracking again within this long after the fault ends or the operator acts (s)."""
TRACKING_S = 1.0
"""Tracking again: this long of live output with at least TRACKING_FRACTION of the ticks enabled (s)."""
TRACKING_FRACTION = 0.9
SELF_RECOVERY_S = 2.0
"""After a blackout or a board restart, how long the soak waits before re-activating the bridge as an
operator would (s)."""
ENABLED_BIT = 0x1
BRIDGE = "/smm/hw_bridge_node"
CONTROLLER = "/smm/controller_node"
GAIN = "fpdeso.fuzzy.kd0"
GAIN_VALUES = ([110.0, 90.0], [121.0, 99.0])
"""kd0 (1/s) of the scenario and +10 %, alternated."""


@dataclass
class FaultResult:
    """One fault: when, what its criterion measured, whether it held."""

    name: str
    started_s: float
    ok: bool
    null_ticks: int | None = None
    """Ticks from the last tick the host could have answered to the valves at null (None: not applicable)."""
    recovery_s: float | None = None
    """Fault end (or operator action) to tracking again (s)."""
    operator: str = ""
    detail: str = ""
    ended_s: float = 0.0


class Board:
    """The emulator's JSON control port."""

    def __init__(self, address: tuple[str, int] = ("127.0.0.1", 50102)) -> None:
        self.address = address
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind(("127.0.0.1", 0))
        self.socket.settimeout(1.0)

    def ask(self, request: dict[str, Any]) -> dict[str, Any] | None:
        """Sends one request; the reply (None when none came within a second, twice)."""
        for _ in range(2):
            self.socket.sendto(json.dumps(request).encode(), self.address)
            try:
                while True:
                    data, _ = self.socket.recvfrom(65536)
                    reply = json.loads(data)
                    if isinstance(reply, dict):
                        return reply
            except TimeoutError:
                continue
        return None

    def status(self) -> dict[str, Any] | None:
        """``{"status": true}``."""
        return self.ask({"status": True})

    def live(self) -> bool:
        """The valves driven by an enabled command now."""
        status = self.status()
        return bool(
            status
            and status.get("status_bits", 0) & ENABLED_BIT
            and not status.get("estop")
            and status.get("output_codes") != [0, 0]
        )

    def close(self) -> None:
        """Closes the socket."""
        self.socket.close()


def wait_null(board: Board, deadline_s: float) -> dict[str, Any] | None:
    """Polls until the valves are at null; that status (with ``null_since_tick``), or None by the deadline."""
    while time.monotonic() < deadline_s:
        status = board.status()
        if status and status.get("output_codes") == [0, 0] and status.get("null_since_tick") is not None:
            return status
        time.sleep(0.003)
    return None


def wait_tracking(board: Board, timeout_s: float) -> float | None:
    """Seconds until the output is live and stays enabled for TRACKING_S; None if not within ``timeout_s``."""
    start = time.monotonic()
    while time.monotonic() - start < timeout_s:
        if not board.live():
            time.sleep(0.02)
            continue
        live_at = time.monotonic() - start
        first = board.status()
        time.sleep(TRACKING_S)
        last = board.status()
        if first and last and board.live():
            ticks = last["ticks"] - first["ticks"]
            enabled = last["enabled_ticks"] - first["enabled_ticks"]
            if ticks > 0 and enabled >= TRACKING_FRACTION * ticks:
                return live_at
    return None


class Operator:
    """What an operator does through ROS: e-stop, re-arm, lifecycle, parameters (rclpy, own node)."""

    def __init__(self) -> None:
        rclpy.init(signal_handler_options=SignalHandlerOptions.NO)  # Ctrl-C ends the soak, graph stopped
        self._rclpy = rclpy
        self.node = rclpy.create_node("soak_operator")
        self._types = {
            "trigger": Trigger,
            "change": ChangeState,
            "state": GetState,
            "set": SetParameters,
            "get": GetParameters,
        }

    def call(self, kind: str, service: str, request: Any = None, timeout_s: float = 10.0) -> Any:
        """Calls ``service``; its response, or None if it did not answer within ``timeout_s``."""
        service_type = self._types[kind]
        client = self.node.create_client(service_type, service)
        try:
            if not client.wait_for_service(timeout_sec=timeout_s):
                return None
            future = client.call_async(request if request is not None else service_type.Request())
            self._rclpy.spin_until_future_complete(self.node, future, timeout_sec=timeout_s)
            return future.result() if future.done() else None  # type: ignore[no-untyped-call]
        finally:
            self.node.destroy_client(client)

    def trigger(self, service: str) -> str:
        """A std_srvs/Trigger call: ``ok: message`` or why it failed."""
        response = self.call("trigger", service)
        if response is None:
            return "no answer"
        return f"{'ok' if response.success else 'refused'}: {response.message}"

    def lifecycle_state(self) -> int | None:
        """The bridge's lifecycle state id (lifecycle_msgs/State), None without an answer."""
        response = self.call("state", f"{BRIDGE}/get_state", GetState.Request())
        return None if response is None else int(response.current_state.id)

    def reactivate(self) -> str:
        """Arms the bridge again (after SESSION_LOST): the transitions its lifecycle state allows, to active.

        Only valid transitions are asked for: an invalid one raises inside rclpy's lifecycle service and
        ends the process (docs/SOAK.md, "Findings").
        """
        state = self.lifecycle_state()
        steps = {
            State.PRIMARY_STATE_ACTIVE: (Transition.TRANSITION_DEACTIVATE, Transition.TRANSITION_ACTIVATE),
            State.PRIMARY_STATE_INACTIVE: (Transition.TRANSITION_ACTIVATE,),
            State.PRIMARY_STATE_UNCONFIGURED: (
                Transition.TRANSITION_CONFIGURE,
                Transition.TRANSITION_ACTIVATE,
            ),
        }.get(state if state is not None else -1)
        if steps is None:
            return f"lifecycle state {state}: no way back to active"
        said = []
        for transition in steps:
            request = ChangeState.Request()
            request.transition.id = transition
            response = self.call("change", f"{BRIDGE}/change_state", request)
            said.append(f"{transition}:{'no answer' if response is None else bool(response.success)}")
        return f"from state {state}: transitions {' '.join(said)}"

    def set_gain(self, values: list[float]) -> str:
        """Sets GAIN on the controller, reads it back; ``""`` when it took, else why not."""
        request = SetParameters.Request()
        value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=values)
        request.parameters = [Parameter(name=GAIN, value=value)]
        response = self.call("set", f"{CONTROLLER}/set_parameters", request)
        if response is None:
            return "set_parameters did not answer"
        if not response.results[0].successful:
            return f"refused: {response.results[0].reason}"
        get = GetParameters.Request()
        get.names = [GAIN]
        read = self.call("get", f"{CONTROLLER}/get_parameters", get)
        if read is None:
            return "get_parameters did not answer"
        back = list(read.values[0].double_array_value)
        return "" if back == values else f"read back {back}, set {values}"

    def close(self) -> None:
        """Destroys the node and shuts rclpy down."""
        self.node.destroy_node()  # type: ignore[no-untyped-call]
        with contextlib.suppress(Exception):
            self._rclpy.shutdown()


def _null_result(
    name: str, started: float, null_status: dict[str, Any] | None, last_tick: int, slack: int
) -> tuple[bool, int | None, str]:
    """Valves at null within validity (+ramp +``slack``) of ``last_tick``, the last tick the host answered."""
    if null_status is None:
        return False, None, "valves never seen at null"
    ticks = int(null_status["null_since_tick"]) - last_tick
    limit = VALIDITY_TICKS + RAMP_TICKS + slack
    return ticks <= limit, ticks, f"null {ticks} ticks after the last answerable tick (limit {limit})"


def recover(board: Board, result: FaultResult, action: Callable[[], str] | None) -> None:
    """Waits SELF_RECOVERY_S for tracking again by itself, else runs ``action`` (the operator) and waits.

    ``result.recovery_s``: seconds to live output from the wait's start (or from the operator's action).
    """
    seconds = wait_tracking(board, SELF_RECOVERY_S)
    if seconds is None and action is not None:
        result.operator = action()
        seconds = wait_tracking(board, RECOVERY_LIMIT_S)
    result.recovery_s = seconds
    if seconds is None:
        result.ok = False
        result.detail += f"; not tracking again within {RECOVERY_LIMIT_S:g} s"


def blackout(board: Board, operator: Operator, now: Callable[[], float]) -> FaultResult:
    """100 ms without feedback (the board's 100 frames silent): the host has nothing to answer."""
    started = now()
    reply = board.ask({"fault": "silent", "count": 100})
    if reply is None:
        return FaultResult("blackout 100 ms", started, False, detail="control port did not answer")
    null = wait_null(board, time.monotonic() + 0.5)
    ok, ticks, detail = _null_result("blackout", started, null, int(reply["tick"]), 0)
    result = FaultResult("blackout 100 ms", started, ok, ticks, detail=detail)
    time.sleep(0.1)
    recover(board, result, operator.reactivate)
    result.ended_s = now()
    return result


def board_restart(board: Board, operator: Operator, now: Callable[[], float]) -> FaultResult:
    """``{"reboot": true}``: new session, valves at null at boot; the bridge must be armed again."""
    started = now()
    before = board.status()
    reply = board.ask({"reboot": True})
    if reply is None or before is None:
        return FaultResult("board restart", started, False, detail="control port did not answer")
    ok = reply.get("output_codes") == [0, 0] and reply.get("session") != before.get("session")
    result = FaultResult(
        "board restart", started, ok, 0 if ok else None,
        detail="null at boot, new session" if ok else f"after reboot: {reply.get('output_codes')}",
    )  # fmt: skip
    recover(board, result, operator.reactivate)
    result.ended_s = now()
    return result


def _gone(pid: int, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            return True
        if stat.rsplit(")", 1)[1].split()[0] in ("Z", "X"):
            return True
        time.sleep(0.001)
    return False


def kill_controller(
    board: Board, operator: Operator, now: Callable[[], float], pid: int | None, respawned: Callable[[], bool]
) -> FaultResult:
    """SIGKILL of the controlling process (direct_loop); smm-launch --respawn starts it again."""
    started = now()
    if pid is None:
        return FaultResult("SIGKILL controller", started, False, detail="no controller pid")
    os.kill(pid, signal.SIGKILL)
    if not _gone(pid, 2.0):
        return FaultResult("SIGKILL controller", started, False, detail=f"pid {pid} still alive")
    after = board.status()
    if after is None:
        return FaultResult("SIGKILL controller", started, False, detail="control port did not answer")
    null = wait_null(board, time.monotonic() + 0.5)
    ok, ticks, detail = _null_result("kill", started, null, int(after["tick"]), 0)
    result = FaultResult("SIGKILL controller", started, ok, ticks, detail=detail)
    killed_at = time.monotonic()
    seconds = wait_tracking(board, 30.0)
    result.operator = "respawned by smm-launch" if respawned() else "NOT respawned"
    result.recovery_s = None if seconds is None else time.monotonic() - killed_at - TRACKING_S
    result.detail += f"; respawn to tracking {result.recovery_s if seconds else 'never'}"
    if seconds is None or not respawned():
        result.ok = False
    result.ended_s = now()
    return result


def estop(board: Board, operator: Operator, now: Callable[[], float]) -> FaultResult:
    """The bridge's ~/estop, then ~/rearm (activate again if it stays disarmed)."""
    started = now()
    before = board.status()
    said = operator.trigger(f"{BRIDGE}/estop")
    answered = board.status()  # the bridge sent ESTOP before it answered the service call
    null = wait_null(board, time.monotonic() + 0.5)
    status = board.status()
    if before is None or answered is None or status is None:
        return FaultResult("e-stop + re-arm", started, False, detail="control port did not answer")
    ok, ticks, detail = _null_result("estop", started, null, int(answered["tick"]), 0)
    ok = ok and bool(status.get("estop"))
    call_ticks = int(answered["tick"]) - int(before["tick"])
    result = FaultResult(
        "e-stop + re-arm",
        started,
        ok,
        ticks,
        detail=f"estop {said} ({call_ticks} ticks for the call); {detail}",
    )
    time.sleep(0.5)
    rearm = operator.trigger(f"{BRIDGE}/rearm")
    result.operator = f"rearm {rearm}"

    def activate() -> str:
        return f"rearm {rearm}; {operator.reactivate()}"

    recover(board, result, activate)
    result.ended_s = now()
    return result


def gains(board: Board, operator: Operator, now: Callable[[], float], index: int) -> FaultResult:
    """A gain change through parameters (kd0 +10 % or back): set, read back, the loop undisturbed."""
    started = now()
    values = GAIN_VALUES[index % 2]
    first = board.status()
    why = operator.set_gain(values)
    time.sleep(1.0)
    last = board.status()
    steady = _undisturbed(first, last)
    ok = not why and not steady
    detail = f"{GAIN} = {values}: " + (why or "applied, read back") + (f"; {steady}" if steady else "")
    return FaultResult("gain change", started, ok, detail=detail, ended_s=now())


def _undisturbed(first: dict[str, Any] | None, last: dict[str, Any] | None) -> str:
    """Empty when the board stayed live with the same session between two statuses, else what changed."""
    if first is None or last is None:
        return "control port did not answer"
    if first["session"] != last["session"] or last.get("estop"):
        return "board session or e-stop changed"
    ticks = last["ticks"] - first["ticks"]
    enabled = last["enabled_ticks"] - first["enabled_ticks"]
    if ticks <= 0 or enabled < TRACKING_FRACTION * ticks:
        return f"enabled {enabled} of {ticks} ticks"
    if last.get("null_since_tick") is not None:
        return "valves at null"
    return ""


def garbage(board: Board, operator: Operator, now: Callable[[], float], seed: int) -> FaultResult:
    """A garbage burst: random datagrams at the bridge's and board's ports, corrupt frames from the board."""
    started = now()
    rng = random.Random(seed)
    first = board.status()
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for _ in range(200):
            for port in (50100, 50101):
                sender.sendto(rng.randbytes(rng.randint(1, 600)), ("127.0.0.1", port))
        board.ask({"fault": "corrupt", "count": 5})
        for _ in range(20):
            sender.sendto(rng.randbytes(rng.randint(1, 100)), board.address)
    finally:
        sender.close()
    time.sleep(1.0)
    last = board.status()
    disturbed = _undisturbed(first, last)
    detail = "400 random datagrams, 5 corrupt feedback frames, 20 at the control port"
    return FaultResult(
        "garbage burst",
        started,
        not disturbed,
        detail=detail + (f"; {disturbed}" if disturbed else ""),
        ended_s=now(),
    )
