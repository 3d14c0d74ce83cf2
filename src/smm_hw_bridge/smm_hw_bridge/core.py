"""The bridge's logic without ROS or sockets: sessions, arming, watchdog, stale refusal, soft limits, e-stop.

Device readings in (:meth:`BridgeCore.on_feedback`; bytes: :meth:`BridgeCore.on_datagram`), torque
commands in (:meth:`BridgeCore.on_command`), command frames out (:meth:`BridgeCore.next_frame`); times are
integer ns passed in. The states and their
transitions are drawn in docs/HW_PROTOCOL.md ("Host state machine").
"""

from __future__ import annotations

import enum
import math
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from smm_hw_bridge.bridge_config import BridgeConfig
from smm_hw_bridge.control_rate import is_control_tick
from smm_hw_bridge.encoder import EncoderDecoder
from smm_hw_bridge.link import FeedbackAdmission, LinkStats
from smm_hw_bridge.pressure import LoadTorque
from smm_hw_bridge.protocol import (
    CommandFlag,
    CommandFrame,
    FeedbackFrame,
    ProtocolError,
    Reason,
    StatusBit,
    decode_feedback,
)
from smm_hw_bridge.safety_stop import SafetyStop
from smm_hw_bridge.valve_output import ValveOutput

__all__ = ["BridgeConfig", "BridgeCore", "BridgeError", "BridgeState", "Refusal"]

FloatArray = npt.NDArray[np.float64]
_RECENT_KEPT = 64
_ENABLE = int(CommandFlag.ENABLE)
_ESTOP = int(CommandFlag.ESTOP)
_REARM = int(CommandFlag.REARM)
_ESTOP_LATCHED = int(StatusBit.ESTOP_LATCHED)


class BridgeState(enum.Enum):
    """Where the bridge is; only ARMED ever sends an enabled command."""

    DISCONNECTED = "disconnected"
    DISARMED = "disarmed"
    ARMING = "arming"
    ARMED = "armed"
    ESTOP = "estop"
    FAULT = "fault"
    SESSION_LOST = "session_lost"


class Refusal(enum.Enum):
    """Why a torque command was not used."""

    INVALID = "invalid"
    INACTIVE = "inactive"
    UNKNOWN_STAMP = "unknown_stamp"
    STALE = "stale"
    BEFORE_ARM = "before_arm"


class BridgeError(RuntimeError):
    """An operation the bridge's state does not allow (e.g. arming with a board fault)."""


@dataclass(slots=True)
class _Pending:
    codes: tuple[int, int]
    answers_seq: int
    answers_tick: int
    answers_tick_unwrapped: int
    rx_ns: int


def _finite_pair(torque: npt.ArrayLike) -> tuple[float, float] | None:
    """(alpha, beta) of a finite array-like of shape (2,) as Python floats; None for anything else."""
    if isinstance(torque, (tuple, list)) and len(torque) == 2:
        alpha, beta = torque
        if type(alpha) is float and type(beta) is float:
            return (alpha, beta) if math.isfinite(alpha) and math.isfinite(beta) else None
    if isinstance(torque, str):
        return None
    demand = np.asarray(torque, dtype=np.float64)
    if demand.shape != (2,) or not np.all(np.isfinite(demand)):
        return None
    return float(demand[0]), float(demand[1])


class BridgeCore:
    """Host side of the link. One instance per configured session.

    Args:
        config: The bridge configuration.
        host_session: This bridge's session id (new at every configure), in [1, 2**32).
    """

    def __init__(self, config: BridgeConfig, host_session: int) -> None:
        if (
            isinstance(host_session, bool)
            or not isinstance(host_session, int)
            or not 0 < host_session < 1 << 32
        ):
            raise ValueError(f"host_session must be an int in [1, 2**32), got {host_session!r}")
        self._config = config
        self._host_session = host_session
        self._period_ns = config.period_ns
        self._period_s = config.period_ns / 1e9
        self._command_dt = config.period_ns * config.control_divider * 1e-9
        """dt of the valve's rate limit per command (s): one command a control period of N ticks (at 200 Hz
        a 1 ms dt slewed full scale in 10 ms, not 2, and the loop on the emulated bench went unstable)."""
        self._limits = (float(config.soft_limits[0]), float(config.soft_limits[1]))
        self._safety = SafetyStop(config.limit_stop, self._limits, config.period_ns)
        self._validity = config.validity
        self._stale_ticks = config.stale_ticks
        self._watchdog_ns = config.watchdog_ns
        self._divider = config.control_divider
        self._encoder = EncoderDecoder(config.encoder)
        self._count_limit = config.encoder.modulus
        self._valve = ValveOutput(config.valve, config.control_divider)
        self._admission = FeedbackAdmission(config.admission)
        self._load = LoadTorque(config.pressure)
        self.stats = LinkStats()
        self.refused: dict[Refusal, int] = {}
        self.watchdog_trips = 0
        self.reboots = 0
        self.reset()

    def reset(self) -> None:
        """Back to DISCONNECTED with no board session; counters are kept."""
        self.state = BridgeState.DISCONNECTED
        self.board_session: int | None = None
        self._candidate: tuple[int, int] | None = None
        self._encoder.reset()
        self._valve.reset()
        self._admission.reset()
        self._safety.reset()
        self.stats.reset_sequence()
        self._recent: OrderedDict[int, tuple[int, int]] = OrderedDict()
        self._last: FeedbackFrame | None = None
        self._last_rx_ns: int | None = None
        self._effort = (0.0, 0.0)
        self._period_effort = (0.0, 0.0)  # N > 1: the mean of the ticks since the last control tick
        self._period_sum = (0.0, 0.0, 0)
        self._measured = (0.0, 0.0)
        self._tick = 0
        self._pending: _Pending | None = None
        self._active = False
        self._arm_tick = -1
        self._stepped_tick = -1  # the measurement tick the valve output last stepped for
        self._estop_requested = False
        self._rearm_pending = False
        self._seq = 0
        self._live = False
        self._cut = (False, False)
        self.last_rejection: Reason | None = None
        """Why the last received frame was dropped (None if it was admitted)."""

    @property
    def config(self) -> BridgeConfig:
        """The configuration."""
        return self._config

    @property
    def host_session(self) -> int:
        """This bridge's session id."""
        return self._host_session

    @property
    def rejected(self) -> Mapping[Reason, int]:
        """Dropped received frames by reason (parser, session, admission)."""
        return self._admission.rejected

    @property
    def last_feedback(self) -> FeedbackFrame | None:
        """The last admitted feedback frame."""
        return self._last

    @property
    def output_live(self) -> bool:
        """True if the last frame sent carried ENABLE."""
        return self._live

    # ---- feedback ---------------------------------------------------------------------------------

    def on_datagram(self, data: bytes, rx_ns: int) -> FeedbackFrame | None:
        """Parses, checks and uses one received frame; returns it if admitted, None if dropped (counted)."""
        try:
            frame = decode_feedback(data)
        except ProtocolError as error:
            return self.on_feedback(error.reason, rx_ns)
        return self.on_feedback(frame, rx_ns)

    def on_feedback(self, reading: FeedbackFrame | Reason, rx_ns: int) -> FeedbackFrame | None:
        """Checks and uses a device's reading (feedback, or why it was refused); the feedback if admitted."""
        if isinstance(reading, Reason):
            self._admission.count(reading)
            self.last_rejection = reading
            return None
        frame = reading
        self.last_rejection = None
        # counts wider than the configured counters: malformed (a u32 on the wire), dropped before any use
        limit = self._count_limit
        if frame.counts[0] >= limit or frame.counts[1] >= limit:
            self._admission.count(Reason.FIELD)
            self.last_rejection = Reason.FIELD
            return None
        if self.board_session is None:
            self._adopt(frame.session)
        elif frame.session != self.board_session:
            self._admission.count(Reason.SESSION)
            self._foreign(frame.session)
            if frame.session != self.board_session:
                return None
        self._candidate = None
        self.last_rejection = self._admission.admit(frame, rx_ns)
        if self.last_rejection is not None:
            return None
        self._use(frame, rx_ns)
        return frame

    def _adopt(self, session: int) -> None:
        self.board_session = session
        self._candidate = None
        self._admission.reset()
        self._safety.reset()
        self.stats.reset_sequence()
        self._recent.clear()
        self._pending = None
        self._last = None
        if self.state == BridgeState.DISCONNECTED:
            self.state = BridgeState.DISARMED

    def _foreign(self, session: int) -> None:
        count = self._candidate[1] + 1 if self._candidate and self._candidate[0] == session else 1
        self._candidate = (session, count)
        if count < self._config.reboot_frames:
            return
        self.reboots += 1
        if self.state in (BridgeState.ARMING, BridgeState.ARMED):
            self._lose_session()
        self._adopt(session)  # safe frames to the new board from now on; output only after arm()

    def _lose_session(self) -> None:
        self.state = BridgeState.SESSION_LOST
        self._pending = None
        self._valve.reset()

    def _use(self, frame: FeedbackFrame, rx_ns: int) -> None:
        self._encoder.update_floats(frame.counts)
        previous = None if self._last is None else self._tick
        tick = self._tick = self._admission.tick
        self._recent[tick] = (frame.seq, frame.tick)
        while len(self._recent) > _RECENT_KEPT:
            self._recent.popitem(last=False)
        self.stats.on_feedback(frame.seq, frame.applied_seq, rx_ns)
        self._last, self._last_rx_ns = frame, rx_ns
        # the valves' lag over the ticks since the last feedback: 1 from a board, N from a CANopen SYNC
        ticks = 1 if previous is None else min(max(tick - previous, 1), self._divider)
        self._effort = self._valve.effort_floats(frame.output_codes, self._period_s * ticks)
        if self._divider > 1:
            self._average_effort(frame.tick, ticks)
        self._measured = self._load.torque(frame.adc)
        self._safety.on_feedback(tick, self._encoder.position_floats, self._effort, self._live)
        if frame.faults:
            self.state = BridgeState.FAULT
            self._pending = None
            self._valve.reset()
            return
        latched = bool(frame.status & _ESTOP_LATCHED)
        if self._rearm_pending and not latched and not self._estop_requested:
            self._rearm_pending = False
            self.state = BridgeState.ARMING if self._active else BridgeState.DISARMED
            self._arm_tick = tick
        elif latched and self.state != BridgeState.ESTOP and not self._rearm_pending:
            self.state = BridgeState.ESTOP
            self._pending = None
        elif self.state == BridgeState.FAULT:
            pass  # stays until reset: the lifecycle error path reconfigures

    def _average_effort(self, board_tick: int, ticks: int) -> None:
        """Adds this feedback's ticks to the period's mean effort; a control tick closes the period."""
        sum_a, sum_b, count = self._period_sum
        sum_a += self._effort[0] * ticks
        sum_b += self._effort[1] * ticks
        count += ticks
        if is_control_tick(board_tick, self._divider):
            self._period_effort = (sum_a / count, sum_b / count)
            sum_a, sum_b, count = 0.0, 0.0, 0
        self._period_sum = (sum_a, sum_b, count)

    def limit_stop(self) -> str | None:
        """Why the run must stop while arming or armed (:class:`~smm_hw_bridge.safety_stop.SafetyStop`)."""
        if self.state not in (BridgeState.ARMING, BridgeState.ARMED):
            return None
        return self._safety.reason()

    @property
    def control_tick(self) -> bool:
        """True if the controller answers the last admitted feedback (its board tick a multiple of N)."""
        last = self._last
        return last is not None and is_control_tick(last.tick, self._divider)

    @property
    def stamp_ns(self) -> int:
        """Stamp of the last admitted measurement: unwrapped board tick * period (ns)."""
        return self._admission.tick * self._period_ns

    @property
    def position(self) -> FloatArray:
        """Last measured joint angle (alpha, beta) (rad)."""
        return self._encoder.position

    @property
    def position_floats(self) -> tuple[float, float]:
        """:attr:`position` as Python floats (alpha, beta) (rad), without building an array."""
        return self._encoder.position_floats

    @property
    def applied_torque(self) -> FloatArray:
        """Torque the valves gave over the last control period (N m), shape (2,); 0 before any feedback.

        The D/A codes the board reports, through the valve lag model (``valve.time_constants``); at a divider
        N > 1 the mean over the ticks since the control tick before (one feedback of N ticks on CANopen, N
        of one tick on the frame link), at N = 1 the last tick's.
        """
        return np.array(self.applied_torque_floats, dtype=np.float64)

    @property
    def applied_torque_floats(self) -> tuple[float, float]:
        """:attr:`applied_torque` as Python floats (alpha, beta) (N m), without building an array."""
        return self._period_effort if self._divider > 1 else self._effort

    @property
    def measured_torque(self) -> FloatArray:
        """Torque the actuators gave over the last tick, from the load pressure (N m), shape (2,).

        A/D channels 1 and 2 through ``pressure``; 0 before any feedback.
        """
        return np.array(self._measured, dtype=np.float64)

    @property
    def supply_pressure_bar(self) -> float:
        """Supply pressure of A/D channel 0 (bar), NaN before any feedback."""
        return math.nan if self._last is None else self._last.adc[0] * self._config.supply_bar_per_code

    # ---- commands ---------------------------------------------------------------------------------

    def _refuse(self, why: Refusal) -> Refusal:
        self.refused[why] = self.refused.get(why, 0) + 1
        return why

    def on_command(self, torque: npt.ArrayLike, stamp_ns: int, rx_ns: int) -> Refusal | None:
        """Takes a torque command answering the measurement stamped ``stamp_ns``; None if accepted.

        ``torque`` (alpha, beta) (N m): any array-like of shape (2,); a tuple or list of two Python floats
        is the fast path. A refused command (reason returned and counted) changes nothing.
        """
        demand = _finite_pair(torque)
        if demand is None or isinstance(stamp_ns, bool):
            return self._refuse(Refusal.INVALID)
        if self.state not in (BridgeState.ARMING, BridgeState.ARMED):
            return self._refuse(Refusal.INACTIVE)
        tick, remainder = divmod(int(stamp_ns), self._period_ns)
        entry = self._recent.get(tick) if remainder == 0 else None
        if entry is None:
            return self._refuse(Refusal.UNKNOWN_STAMP)
        if self._admission.tick - tick > self._stale_ticks:
            return self._refuse(Refusal.STALE)
        if tick <= self._arm_tick:
            return self._refuse(Refusal.BEFORE_ARM)
        position_a, position_b = self._encoder.position_floats
        limit_a, limit_b = self._limits
        alpha, beta = demand
        cut_a = (position_a >= limit_a and alpha > 0.0) or (position_a <= -limit_a and alpha < 0.0)
        cut_b = (position_b >= limit_b and beta > 0.0) or (position_b <= -limit_b and beta < 0.0)
        self._cut = (cut_a, cut_b)
        again = tick == self._stepped_tick  # a re-sent feedback answered again (lockstep): one step a tick
        self._stepped_tick = tick
        demand = (0.0 if cut_a else alpha, 0.0 if cut_b else beta)
        codes = self._valve.step_floats(demand, self._command_dt, again)
        self._pending = _Pending(codes, entry[0], entry[1], tick, rx_ns)
        last = self._last
        # lockstep: the board re-sends the feedback it built before it locked to us (the board itself drops
        # enabled frames from a host it is not locked to)
        locked = last is not None and (last.host_session == self._host_session or self._config.lockstep)
        if self.state == BridgeState.ARMING and locked and self._admission.tick > self._arm_tick:
            self.state = BridgeState.ARMED
        return None

    def next_frame(self, now_ns: int) -> CommandFrame | None:
        """The frame to send now: safe output unless ARMED with a fresh command; None without feedback."""
        self.check_link(now_ns)
        if self.board_session is None or self._last is None:
            return None
        pending = self._pending
        flags = 0
        codes = (0, 0)
        answers_seq, answers_tick = self._last.seq, self._last.tick
        if self._estop_requested:
            flags = _ESTOP
        elif self._rearm_pending:
            flags = _REARM
        elif self.state == BridgeState.ARMED and pending is not None:
            fresh = now_ns - pending.rx_ns <= self._watchdog_ns
            valid = self._admission.tick - pending.answers_tick_unwrapped <= self._validity
            if fresh and valid:
                flags = _ENABLE
                codes = pending.codes
                answers_seq, answers_tick = pending.answers_seq, pending.answers_tick
            else:
                self.watchdog_trips += 1
                self._pending = None
                self._valve.reset()
        self._live = flags == _ENABLE
        if not self._live:
            self._valve.reset()
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        # every field is checked already: sessions and feedback fields by the decoder, validity by the
        # config, codes by the valve output's clamp to code_limit
        frame = CommandFrame.trusted(
            session=self._host_session,
            seq=self._seq,
            board_session=self.board_session,
            answers_seq=answers_seq,
            answers_tick=answers_tick,
            flags=flags,
            validity=self._validity,
            codes=codes,
        )
        self.stats.on_command_sent(frame.seq, now_ns)
        return frame

    def needs_frame(self, now_ns: int) -> bool:
        """True when a frame should go out without a new command (output not live, or its command aged)."""
        pending = self._pending
        if self.state != BridgeState.ARMED or pending is None:
            return True
        if now_ns - pending.rx_ns > self._watchdog_ns:
            return True
        return self._admission.tick - pending.answers_tick_unwrapped > self._validity

    def link_up(self, now_ns: int) -> bool:
        """True if feedback was admitted within ``link_timeout_ns`` (no state change)."""
        return self._last_rx_ns is not None and now_ns - self._last_rx_ns <= self._config.link_timeout_ns

    def check_link(self, now_ns: int) -> bool:
        """True if feedback was admitted within ``link_timeout_ns``.

        A link loss while the output is armed loses the session: output disabled until :meth:`arm`. While
        arming (the output never went live) it does not: arming completes on feedback after the gap.
        """
        up = self.link_up(now_ns)
        if not up and self._active and self.state == BridgeState.ARMED:
            self._lose_session()
        return up

    # ---- operator actions ---------------------------------------------------------------------------

    def arm(self) -> None:
        """Activation: output goes live after a newer valid feedback and a command answering it.

        Raises:
            BridgeError: no board session yet, a board fault, or an e-stop latched.
        """
        if self.state == BridgeState.FAULT:
            raise BridgeError("the board reports fault bits: reset (reconfigure) before arming")
        if self.state == BridgeState.ESTOP or self._estop_requested:
            raise BridgeError("e-stop latched: re-arm it first")
        if self.board_session is None or self._last is None:
            raise BridgeError("no valid feedback from the board yet")
        self._active = True
        self._pending = None
        self._valve.reset()
        self._safety.arm()
        self._arm_tick = self._admission.tick - (1 if self._config.lockstep else 0)
        self.state = BridgeState.ARMING

    def disarm(self) -> None:
        """Deactivation: safe output from the next frame on; ESTOP and FAULT stay."""
        self._active = False
        self._pending = None
        self._valve.reset()
        if self.state in (BridgeState.ARMING, BridgeState.ARMED, BridgeState.SESSION_LOST):
            self.state = BridgeState.DISARMED if self.board_session is not None else BridgeState.DISCONNECTED

    def estop(self) -> None:
        """Latches an e-stop: every frame carries ESTOP until :meth:`rearm`."""
        self._estop_requested = True
        self._rearm_pending = False
        self._pending = None
        self._valve.reset()
        self.state = BridgeState.ESTOP

    def rearm(self) -> None:
        """Clears the e-stop: frames carry REARM until the board reports its latch cleared.

        After that the output needs a fresh measurement and command again.

        Raises:
            BridgeError: no e-stop is latched.
        """
        if self.state != BridgeState.ESTOP:
            raise BridgeError(f"nothing to re-arm: state is {self.state.value}")
        self._estop_requested = False
        self._rearm_pending = True

    @property
    def internals(self) -> Mapping[str, FloatArray]:
        """What was last sent, shape (2,) each.

        Keys: ``codes``, ``torque`` (N m), ``clamped`` (saturation or rate limit, 0/1), ``limit_cut``
        (soft limit, 0/1), ``enabled`` (0/1); and ``measured_torque`` (N m), the load pressure's torque
        over the tick before the last admitted feedback (:attr:`measured_torque`).
        """
        values = dict(self._valve.internals)
        values["limit_cut"] = np.array(self._cut, dtype=np.float64)
        values["enabled"] = np.full(2, 1.0 if self._live else 0.0)
        values["measured_torque"] = self.measured_torque
        return values
