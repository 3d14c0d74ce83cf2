"""The bridge's tick over a :class:`~smm_hw_bridge.device.Device`, pure (no ROS): ros2_control's loop.

:meth:`BridgeLoop.on_feedback` admits a feedback and, given an :class:`Answerer` (the direct loop's
controller), answers and writes in the same call; :meth:`BridgeLoop.on_command` takes the topics loop's
``torque_command``. Parameter changes come through a :class:`ChangeBuffer`, applied between ticks. The
preflight rehearses here (:meth:`BridgeLoop.rehearse`). Drawn in docs/DESIGN.md, "The bridge's loop".
"""

from __future__ import annotations

import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Mapping
from typing import Final, NamedTuple, Protocol

import numpy as np
import numpy.typing as npt
from smm_node_runtime.health import Health

from smm_hw_bridge.bridge_health import BridgeCounters, bridge_health, with_loop_figures
from smm_hw_bridge.core import BridgeCore, BridgeError, BridgeState
from smm_hw_bridge.device import Device, DeviceError, Reading
from smm_hw_bridge.loop_statistics import LoopStatistics, RunningFigures
from smm_hw_bridge.preflight import RehearsalRecorder
from smm_hw_bridge.protocol import CommandFrame, Reason
from smm_hw_bridge.reading import LINK_CHECK_S, LoopSettings, next_reading
from smm_hw_bridge.run_verdict import RunTally

__all__ = [
    "LINK_CHECK_S",
    "REHEARSAL_STAMP_OFFSET_NS",
    "Answerer",
    "BridgeLoop",
    "ChangeBuffer",
    "Tick",
    "first_feedback",
]

_LINK_CHECK_NS: Final[int] = round(LINK_CHECK_S * 1e9)
REHEARSAL_STAMP_OFFSET_NS: Final[int] = 3_600_000_000_000
"""What the rehearsal publishes is stamped this much (1 h) after the board's tick: the analysis leaves it out
(``smm_analysis.runs.stream``), and in the topics loop the armed run's first measurements are a backward time
jump, on which ``controller_node`` starts it afresh."""
FloatArray = npt.NDArray[np.float64]
_DONE: Final[int] = -1
"""A tick whose answer faulted: its safe frame went out, nothing to publish (stamps are >= 0)."""


class Answerer(Protocol):
    """The controller a loop steps itself (the direct loop's: ``ControllerCore.measurement``)."""

    def answer(
        self, stamp_ns: int, position: tuple[float, float], effort: tuple[float, float]
    ) -> tuple[float, float] | str | None:
        """The torque for a measurement (rad; N m applied); a str: why the chain failed; None: refused."""

    def published(self) -> None:
        """After the send, outside the tick: publishes the last answer."""

    def prepare(self) -> None:
        """After the ROS side: the next step's work that needs no measurement."""

    def forget(self) -> None:
        """The preflight's rehearsal ended: the run starts from fresh state."""


class ChangeBuffer:
    """Changes handed over from any thread, applied in order by the loop's thread at a tick boundary.

    While no loop runs (:attr:`running` False) a change is applied at once.
    """

    def __init__(self) -> None:
        self._changes: deque[Callable[[], None]] = deque()
        self._guard = threading.Lock()
        self._running = False

    def put(self, change: Callable[[], None]) -> None:
        """Hands over ``change`` (validated already)."""
        with self._guard:
            if self._running:
                self._changes.append(change)
                return
            change()

    def apply(self) -> None:
        """Applies the changes handed over (the loop's thread, between ticks)."""
        while self._changes:
            self._changes.popleft()()

    @property
    def running(self) -> bool:
        """True while a loop applies the changes at its tick boundaries."""
        return self._running

    @running.setter
    def running(self, value: bool) -> None:
        with self._guard:
            self._running = value
            if not value:
                self.apply()


class Tick(NamedTuple):
    """What a tick publishes: the sample (stamp ns, position rad, applied torque N m), the stamp answered."""

    stamp_ns: int
    position: FloatArray
    effort: FloatArray
    answered: int | None


class BridgeLoop:
    """The tick: one per bridge node, attached to a core and a device while configured.

    Args:
        counters: The bridge's counts (commands, frames, the last error).
        answerer: The controller it steps on each control tick (direct loop), or None (topics loop).
        changes: Where parameter changes wait for the tick boundary.
        settings: The direct loop's reading policy (``spin_us``); None: one wait of ``LINK_CHECK_S``.
        clock: Monotonic time (ns).
    """

    def __init__(
        self,
        counters: BridgeCounters,
        answerer: Answerer | None = None,
        changes: ChangeBuffer | None = None,
        settings: LoopSettings | None = None,
        clock: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        self.lock = threading.RLock()
        """Held by a tick and by every other use of the core and the device."""
        self.counters = counters
        self.answerer = answerer
        self.changes = changes or ChangeBuffer()
        self.settings = settings
        self._clock = clock
        self.core: BridgeCore | None = None
        self.device: Device | None = None
        self.tally: RunTally | None = None
        """The run's enabled and late ticks from the admitted feedback, from the first attach on."""
        self.rehearsal: RehearsalRecorder | None = None
        """While the preflight rehearses (output disabled): its arrivals and answers."""
        self.statistics = LoopStatistics()
        """Periodicity and receive -> send of the ticks the answerer answered."""
        self.host_fault = ""
        self.safety_stop = ""
        """The first safety stop's reason (:meth:`BridgeCore.limit_stop`), kept for the run's verdict."""
        self.fault_signalled = False
        """Set by :meth:`fail` or :meth:`check`: the node drives the error transition."""
        self._last_rx_ns: int | None = None

    # ---- session ----------------------------------------------------------------------------------

    def connect(
        self, opener: Callable[[], Device], core: BridgeCore, tally: RunTally, timeout_s: float, source: str
    ) -> str | None:
        """Opens the device, waits for ``core`` to admit a feedback, attaches: None, or why not (closed).

        Raises:
            Exception: What a bug raised while waiting (the device is closed first).
        """
        self.host_fault = ""
        try:
            device = opener()
        except DeviceError as error:
            return str(error)
        try:
            why = first_feedback(device, core, timeout_s, source)
        except Exception:
            device.close()
            raise
        if why is not None:
            device.close()
            return why
        self.statistics.reset()
        self.attach(core, device, tally)
        return None

    def attach(self, core: BridgeCore, device: Device, tally: RunTally) -> None:
        """A configured session: safe output at once; changes wait for tick boundaries from now on."""
        with self.lock:
            self.core, self.device, self.host_fault = core, device, ""
            if self.tally is None:
                self.tally = tally
            self.send_safe()
        self.changes.running = True

    def detach(self) -> str | None:
        """Safe output, then the device made safe and closed (the reader thread has stopped).

        Returns what the device could not do to make the valves safe (one line), None if nothing.
        """
        untold = None
        with self.lock:
            if self.core is not None:
                self.core.disarm()
                self.send_safe()
            if self.device is not None:
                untold = self.device.make_safe()
                self.device.close()
            self.device = None
        self.changes.running = False
        return untold

    # ---- the tick ---------------------------------------------------------------------------------

    def run(
        self, stop: threading.Event, publish: Callable[[Tick], None], report: Callable[[str], object]
    ) -> None:
        """The receiving thread until ``stop``: read, tick, ``publish``; the link check every LINK_CHECK_S.

        ``report`` takes the errors (a bug in handling a reading: a host fault; the thread goes on).
        """
        next_check = 0
        while not stop.is_set() and self.device is not None:
            try:
                reading = self.read()
            except OSError as error:
                self.counters.last_error = str(error)
                if stop.wait(LINK_CHECK_S):
                    return
                reading = None
            try:
                if reading is not None:
                    tick = self.on_feedback(reading, self._clock())
                    if tick is not None:
                        publish(tick)
                now = self._clock()
                if reading is None or now >= next_check:  # after the answer went out, not before
                    next_check = now + _LINK_CHECK_NS
                    self.check(now)
            except Exception as error:  # a bug in the host's handling: the reader must outlive it
                if not self.host_fault:  # once: until the error transition the next readings may raise too
                    report(f"reader: handling a datagram raised:\n{traceback.format_exc()}")
                try:
                    self.fail(f"datagram handling raised {type(error).__name__}: {error}")
                except (
                    Exception
                ):  # the safe frame failed too; the host fault is set, the node still fails over
                    report(f"reader: sending the safe frame raised:\n{traceback.format_exc()}")

    def read(self) -> Reading | None:
        """The next reading (waits; with :attr:`settings`, polls from ``spin_us`` before it is due)."""
        device = self.device
        if device is None:
            return None
        spin_us = 0 if self.settings is None else self.settings.spin_us
        reading = next_reading(device, self.core, self._last_rx_ns, spin_us, self._clock)
        self._last_rx_ns = None if reading is None else self._clock()
        return reading

    def on_feedback(self, reading: Reading, rx_ns: int) -> Tick | None:
        """Admits a reading; answers it (with an answerer) or sends what the core wants; what to publish."""
        with self.lock:
            self.changes.apply()  # the tick boundary
            core = self.core
            if core is None or self.device is None:
                return None
            frame = core.on_feedback(reading, rx_ns)
            # lockstep: the board re-sends its unanswered feedback; so do we (a DDS sample may be lost)
            resent = core.config.lockstep and core.last_rejection is Reason.DUPLICATE
            stop = core.limit_stop() if frame is not None or resent else None
            if stop is not None:  # the safe frame goes out at once; the node drives the error transition
                self.safety_stop = self.safety_stop or stop
                self.fail(stop)
                return None
            if frame is None and not resent:
                return None
            # the controller answers every Nth board tick (bridge.control_divider); the board holds between
            armed = core.state in (BridgeState.ARMING, BridgeState.ARMED)
            publish = armed and core.control_tick
            rehearsal = None if armed or frame is None else self.rehearsal
            control = rehearsal is not None and core.control_tick
            if rehearsal is not None:
                answered = self.rehearse(core, rehearsal, rx_ns, control)
            else:
                answered = self._answer(core, rx_ns) if publish and self.answerer is not None else None
                if answered is None and core.needs_frame(rx_ns):
                    out = core.next_frame(rx_ns)
                    if out is not None:
                        self.transmit(out)
            if frame is not None and self.tally is not None:  # the run's figures: after the send
                self.tally.on_feedback(frame)
            if not publish and not control:
                return None
            stamp = core.stamp_ns + (0 if publish else REHEARSAL_STAMP_OFFSET_NS)
            return Tick(stamp, core.position, core.applied_torque, None if answered == _DONE else answered)

    def rehearse(
        self, core: BridgeCore, rehearsal: RehearsalRecorder, rx_ns: int, control: bool
    ) -> int | None:
        """The preflight's tick (lock held): the run's, but a safe frame goes out; the stamp answered.

        Times the arrival; on a control tick the answerer steps on the measurement stamped
        :data:`REHEARSAL_STAMP_OFFSET_NS` ahead, the safe frame is sent, the answer is timed after it (as
        the run's send), and the tick publishes what the run's does, stamped ahead (docs/LAUNCH.md,
        "Preflight"). The topics loop's controller answers the published sample instead (:meth:`on_command`).
        """
        tick = core.stamp_ns // core.config.period_ns
        rehearsal.on_feedback(tick, rx_ns, control)
        stamp = core.stamp_ns + REHEARSAL_STAMP_OFFSET_NS
        answer = self._stepped(stamp) if control and self.answerer is not None else None
        self.send_safe()
        if isinstance(answer, Exception):
            return _DONE
        if not isinstance(answer, tuple):
            return None
        rehearsal.on_answer(tick, self._clock())
        return stamp

    def end_rehearsal(self) -> RehearsalRecorder | None:
        """Ends the rehearsal; the answerer forgets it. Its recorder, None if none ran."""
        with self.lock:
            recorder, self.rehearsal = self.rehearsal, None
            if self.answerer is not None:
                self.answerer.forget()
        return recorder

    def _stepped(self, stamp_ns: int) -> tuple[float, float] | str | Exception | None:
        """The answerer's answer to the core's measurement; the exception a law raised, after :meth:`fail`."""
        assert self.answerer is not None and self.core is not None
        core = self.core
        try:
            return self.answerer.answer(stamp_ns, core.position_floats, core.applied_torque_floats)
        except Exception as error:  # a bug in a law: the loop cannot go on
            self.fail(f"control chain failed at stamp {stamp_ns} ns: {type(error).__name__}: {error}")
            return error

    def _answer(self, core: BridgeCore, rx_ns: int) -> int | None:
        """Steps the answerer and sends its command: the stamp answered.

        :data:`_DONE` after a fault (its safe frame went out); None when nothing was sent.
        """
        stamp_ns = core.stamp_ns
        result = self._stepped(stamp_ns)
        if isinstance(result, Exception):
            return _DONE
        if isinstance(result, str):
            self.fail(f"control chain failed at stamp {stamp_ns} ns: {result}")
            return _DONE
        if result is None or not self.take_command(result, stamp_ns, rx_ns):
            return None
        self.statistics.on_tick(rx_ns, self._clock())
        return stamp_ns

    def on_command(self, torque: npt.ArrayLike, stamp_ns: int, rx_ns: int) -> Mapping[str, FloatArray] | None:
        """The topics loop's ``torque_command``: sent (rehearsing: timed); internals to publish, or None."""
        with self.lock:
            core = self.core
            if core is None or self.device is None:
                return None
            rehearsal = self.rehearsal
            if rehearsal is not None:  # the answer to a rehearsed measurement: timed, never sent
                rehearsal.on_answer((stamp_ns - REHEARSAL_STAMP_OFFSET_NS) // core.config.period_ns, rx_ns)
                return core.internals  # what went out (a safe frame), published as in the run
            if not self.take_command(torque, stamp_ns, rx_ns):
                return None
            return core.internals

    def take_command(self, torque: npt.ArrayLike, stamp_ns: int, rx_ns: int) -> bool:
        """Hands a torque command (N m) to the core, sends the frame it gives (lock held); True if taken."""
        core = self.core
        assert core is not None
        refusal = core.on_command(torque, stamp_ns, rx_ns)
        if refusal is not None:
            self.counters.refused[refusal.value] = self.counters.refused.get(refusal.value, 0) + 1
            return False
        self.counters.commands += 1
        frame = core.next_frame(rx_ns)
        if frame is not None:
            self.transmit(frame)
        return True

    # ---- output -----------------------------------------------------------------------------------

    def send_safe(self) -> None:
        """Sends the frame the core wants now; after disarm that is a safe frame (lock held)."""
        core = self.core
        if core is None or self.device is None:
            return
        frame = core.next_frame(self._clock())
        if frame is not None:
            self.transmit(frame)

    def transmit(self, frame: CommandFrame) -> None:
        """Writes one command to the device and counts it."""
        assert self.device is not None
        try:
            self.device.write(frame)
        except DeviceError as error:
            self.counters.last_error = str(error)
            return
        self.counters.frames_sent += 1
        if not frame.enabled:
            self.counters.safe_frames_sent += 1
        elif self.tally is not None:
            self.tally.armed = True

    def fail(self, reason: str) -> None:
        """A host-side fault (the loop cannot go on): safe frame now; the node drives the error transition."""
        with self.lock:
            self.counters.last_error = reason
            self.host_fault = reason
            if self.core is not None:
                self.core.disarm()
                self.send_safe()
        self.fault_signalled = True

    def estop(self) -> bool:
        """Latches an e-stop and sends it at once; False when not configured."""
        with self.lock:
            if self.core is None or self.device is None:
                return False
            self.core.estop()
            self.send_safe()
        return True

    def rearm(self) -> str | None:
        """Clears the e-stop (sent at once); why not, or None."""
        with self.lock:
            if self.core is None or self.device is None:
                return "not configured"
            try:
                self.core.rearm()
            except BridgeError as error:
                return str(error)
            self.send_safe()
        return None

    def fault(self) -> str | None:
        """What faulted (a host fault, board fault bits), None when nothing did."""
        with self.lock:
            core = self.core
            if core is None:
                return None
            if self.host_fault:
                return f"host fault ({self.host_fault})"
            if core.state != BridgeState.FAULT:
                return None
            last = core.last_feedback
            seen = (
                "" if self.device is None or not self.device.faults else f": {'; '.join(self.device.faults)}"
            )
            return f"board fault bits {0 if last is None else last.faults:#06x}{seen}"

    def health(self, lifecycle: str, publish_us: RunningFigures) -> Health:
        """The bridge's status (:func:`bridge_health`); with an answerer, the loop's figures too."""
        with self.lock:
            dropped = {} if self.device is None else self.device.dropped
            health = bridge_health(
                self.core,
                self.counters,
                dropped,
                host_fault=self.host_fault,
                lifecycle=lifecycle,
                now_ns=self._clock(),
            )
        return health if self.answerer is None else with_loop_figures(health, self.statistics, publish_us)

    def check(self, now_ns: int) -> None:
        """Every ``LINK_CHECK_S`` (receiving thread): link check and host watchdog; a fault is signalled."""
        with self.lock:
            core = self.core
            if core is None or self.device is None:
                return
            core.check_link(now_ns)
            if core.state == BridgeState.ARMED and core.needs_frame(now_ns) and core.output_live:
                out = core.next_frame(now_ns)  # host watchdog: safe output although feedback stopped
                if out is not None:
                    self.transmit(out)
            if core.state == BridgeState.FAULT or self.host_fault:
                self.fault_signalled = True


def first_feedback(device: Device, core: BridgeCore, timeout_s: float, source: str) -> str | None:
    """Reads until ``core`` admits a feedback: None, or after ``timeout_s`` why none came from ``source``."""
    deadline = time.monotonic() + timeout_s
    while core.last_feedback is None and time.monotonic() < deadline:
        reading = device.read(min(0.05, max(deadline - time.monotonic(), 0.0)))
        if reading is not None:
            core.on_feedback(reading, time.monotonic_ns())
    if core.last_feedback is not None:
        return None
    rejected = {reason.value: count for reason, count in core.rejected.items()}
    why = (
        "the board speaks another protocol version"
        if Reason.VERSION in core.rejected
        else "no valid feedback"
    )
    dropped = device.dropped
    return f"{why} from {source} within {timeout_s} s (rejected: {rejected}, transport dropped: {dropped})"
