"""The CANopen link as one :class:`Device`: the bridge masters CiA 408 valves and CiA 406 encoders.

Configure by SDO (:mod:`smm_hw_bridge.canopen_configure`), NMT start, then in lockstep: each
:meth:`CanopenDevice.write` sends the valves' RPDOs and then the SYNC, and :meth:`CanopenDevice.read` gives
the feedback once every node's TPDO for that SYNC has arrived; in real time the read sends each SYNC when
due (:mod:`smm_hw_bridge.sync_clock`). How the bus maps onto :data:`~smm_hw_bridge.device.Feedback`:
docs/HW_CANOPEN.md. No ROS.
"""

from __future__ import annotations

import threading
import time

import can
import canopen

from smm_hw_bridge.can_multicast import MulticastRouteError, loopback_multicast_bus
from smm_hw_bridge.canopen_config import JOINTS, CanopenConfig
from smm_hw_bridge.canopen_configure import (
    ConfigureError,
    await_answer,
    check_bridge,
    check_bus_load,
    configure_node,
    remote_node,
)
from smm_hw_bridge.canopen_feedback import feedback_frame
from smm_hw_bridge.canopen_foreign import NMT_ID, SDO_REQUEST, SYNC_ID, ForeignListener, foreign_message
from smm_hw_bridge.canopen_node import FAULT_BIT, CanNode
from smm_hw_bridge.canopen_safe import tell_disabled, untold_line
from smm_hw_bridge.cia408 import (
    CONTROL_WORD,
    SPOOL_FULL_SCALE,
    SPOOL_SETPOINT,
    STATUS_WORD,
    ValveState,
    control_word,
    state_of_status,
)
from smm_hw_bridge.control_rate import MAX_DIVIDER
from smm_hw_bridge.core import BridgeConfig
from smm_hw_bridge.device import Device, DeviceDescription, DeviceError, Reading, ValveCommand
from smm_hw_bridge.protocol import CommandFlag, FaultBit, FeedbackFrame
from smm_hw_bridge.sync_clock import SyncClock
from smm_hw_bridge.transport import LinkConfig
from smm_hw_bridge.valve_output import ValveOutputConfig

__all__ = ["CanopenDevice", "ConfigureError", "canopen_device"]

_NMT_START_ALL = 0x01
_NMT_STOPPED = 0x04
_NMT_OPERATIONAL = 0x05
_NMT_PRE_OPERATIONAL = 0x7F
_U32 = 1 << 32
_RESEND_S = 0.05
"""Lockstep without a SYNC: the last feedback again after this long (s), as the frame board's resend."""


class CanopenDevice(Device):
    """Two CiA 408 valves and two CiA 406 encoders on one bus, the bridge as master and SYNC producer.

    Args:
        config: The link.
        bus: An open python-can bus to use instead of opening ``config``'s (tests: ``virtual``).
        bridge: The bridge's settings: its valve code limit and control divider (checked at :meth:`open`)
            and its A/D scales (the pressures are handed over as the A/D codes ``bridge.pressure.*`` and
            ``bridge.supply_bar_per_code`` read back); None: the defaults, the code limit at full spool and
            the control divider of ``config.period_us``.
        boot_wait_s: How long :meth:`open` waits for each node's first SDO answer (s): a bench powering up,
            an emulator starting after the bridge (``link.configure_timeout``).
    """

    def __init__(
        self,
        config: CanopenConfig,
        bus: can.BusABC | None = None,
        bridge: BridgeConfig | None = None,
        boot_wait_s: float = 0.0,
    ) -> None:
        super().__init__()
        self.description = DeviceDescription(
            name="canopen",
            joints=JOINTS,
            valves=JOINTS,
            analog=("supply", "load pressure alpha", "load pressure beta", "none"),
            own_watchdog=True,
            validity=False,
        )
        self.config = config
        self.bridge = bridge or BridgeConfig(
            valve=ValveOutputConfig(code_limit=(SPOOL_FULL_SCALE,) * 2),
            control_divider=min(max(config.period_us // 1000, 1), MAX_DIVIDER),
        )
        self._bus = bus
        self._boot_wait_s = boot_wait_s
        self.network: canopen.Network | None = None
        self.nodes: list[CanNode] = []
        self._fault_bits = 0
        self._changed = threading.Condition()
        self._syncs = 0
        self._delivered = 0
        self._boots = 1
        self._host_session = 0
        self._last_seq = 0
        self._estop = False
        self._enabled = False
        self._last_feedback: FeedbackFrame | None = None
        self._delivered_at = 0.0
        self._answered = -1
        self._synced_at = 0.0
        self._heartbeat: can.broadcastmanager.CyclicSendTaskABC | None = None
        self.clock = SyncClock(config.period_us * 1000) if config.sync_clock else None
        """Real time (``sync_clock``): the SYNC schedule, its slots and late periods."""
        self._started = False
        self._faults_delivered = 0
        self._foreign: dict[int, CanNode | None] = {NMT_ID: None, SYNC_ID: None}
        """COB-IDs only this master sends (NMT, SYNC, the valves' RPDO1, SDO requests), and their node."""

    # ---- open: configure and start ----------------------------------------------------------------

    def open(self) -> None:
        """Configures every node by SDO, starts them (NMT) and sends the first SYNC.

        Raises:
            ConfigureError: The bridge's settings do not fit the link (code limit, control divider), or a
                node is missing, of the wrong profile, or differs from its EDS.
            DeviceError: The bus cannot be opened.
        """
        if self.network is not None:
            return
        config = self.config
        check_bridge(config, self.bridge)
        try:
            if self._bus is not None:
                bus = self._bus
            elif config.interface == "udp_multicast":
                bus = loopback_multicast_bus(config.channel, config.port)
            else:
                bus = can.Bus(interface=config.interface, channel=config.channel, bitrate=config.bitrate)
        except (can.CanError, OSError, ValueError, MulticastRouteError) as error:
            raise DeviceError(
                f"cannot open CAN interface {config.interface} {config.channel}: {error}"
            ) from error
        network = canopen.Network(bus)
        network.connect()
        self.network = network
        # frames only the master sends, another's a fault from the NMT start on: a listener of its own,
        # called whatever the canopen library's handlers of the same COB-ID raise (a short NMT frame)
        assert network.notifier is not None
        echoes = self._bus is None and config.interface == "udp_multicast"
        network.notifier.add_listener(ForeignListener(self._on_foreign, self._foreign, bus, echoes))
        try:
            self.nodes = [self._add(network, "valve", j, i) for j, i in enumerate(config.valve_node_ids)]
            self.nodes += [self._add(network, "encoder", j, i) for j, i in enumerate(config.encoder_node_ids)]
            deadline = time.monotonic() + self._boot_wait_s
            for node in self.nodes:
                await_answer(node, deadline)
                configure_node(node, config)
            check_bus_load(config, self.nodes)
        except BaseException:
            self.close()
            raise
        self._heartbeat = bus.send_periodic(
            can.Message(arbitration_id=0x700 + config.master_node_id, data=[5], is_extended_id=False),
            config.heartbeat_ms / 1000.0,
        )
        self.found = tuple(
            f"{node.name}: device type 0x{node.device_type:08X} (CiA {node.device_type & 0xFFFF}), vendor "
            f"0x{node.identity[0]:08X}, product 0x{node.identity[1]:08X}, revision 0x{node.identity[2]:08X}, "
            f"serial 0x{node.identity[3]:08X}"
            for node in self.nodes
        )
        for node in self.nodes:
            node.heard = time.monotonic()  # consumers count from the start
        network.nmt.send_command(_NMT_START_ALL)
        self._started = True
        self._send_safe()

    def _add(self, network: canopen.Network, kind: str, joint: int, node_id: int) -> CanNode:
        """The node, its PDOs and callbacks on ``network``; its COB-IDs only the master sends noted."""
        node = remote_node(self.config, kind, joint, node_id)
        remote = node.remote
        network.add_node(remote)
        remote.tpdo.read(from_od=True)
        remote.rpdo.read(from_od=True)
        remote.tpdo[1].add_callback(lambda pdo, node=node: self._on_tpdo(node, pdo))
        network.subscribe(0x80 + node_id, lambda _id, data, _t, node=node: self._on_emcy(node, bytes(data)))
        network.subscribe(
            0x700 + node_id, lambda _id, data, _t, node=node: self._on_heartbeat(node, bytes(data))
        )
        rpdo = remote.rpdo.map.maps.get(1) if kind == "valve" else None  # none in the EDS: refused later
        foreign = [SDO_REQUEST + node_id] + ([rpdo.cob_id] if rpdo is not None else [])
        for cob_id in foreign:
            self._foreign[cob_id] = node
        return node

    # ---- bus callbacks (the notifier's thread) ----------------------------------------------------

    def _on_tpdo(self, node: CanNode, pdo: canopen.pdo.PdoMap) -> None:
        size = sum(variable.length for variable in pdo) // 8
        with self._changed:
            if len(pdo.data) != size:  # malformed: not the node's (the library cannot decode it)
                what = f"TPDO1 0x{pdo.cob_id:03X} of {len(pdo.data)} bytes, its EDS maps {size}"
                self._fault(node, what, FAULT_BIT[node.kind])
                self._changed.notify_all()
                return
            # lockstep: one a SYNC, a second is another sender's or answers a SYNC not ours (after a fault
            # the TPDOs of a SYNC told early may come after the next); real time: a late one's, not a fault
            if self.clock is None and node.sync == self._syncs and not self._fault_bits:
                self._fault(
                    node, f"TPDO1 0x{pdo.cob_id:03X} twice for SYNC {self._syncs}", FAULT_BIT[node.kind]
                )
            node.values = {variable.index: int(variable.raw) for variable in pdo}
            node.sync = self._syncs
            if node.kind == "valve":
                status = node.values[STATUS_WORD]
                state = state_of_status(status)
                if state is None or state.fault:
                    self._fault(
                        node,
                        f"status word 0x{status:04X} ({state.name if state else 'unknown'})",
                        FaultBit.VALVE_DRIVER,
                    )
            self._changed.notify_all()

    def _on_emcy(self, node: CanNode, data: bytes) -> None:
        code = int.from_bytes(data[:2].ljust(2, b"\0"), "little")
        if code == 0:
            return  # error reset / no error
        with self._changed:
            register = data[2] if len(data) > 2 else 0
            self._fault(node, f"EMCY 0x{code:04X} (error register 0x{register:02X})", FAULT_BIT[node.kind])

    def _on_heartbeat(self, node: CanNode, data: bytes) -> None:
        state = data[0] & 0x7F if data else -1
        with self._changed:
            node.heard, node.lost = time.monotonic(), False
            if state == 0:
                self._boots += 1  # boot-up: a new session
                if self._started:
                    self._fault(node, "boot-up: it reset (its configuration lost)", FaultBit.INTERNAL)
            elif state == _NMT_STOPPED:
                self._fault(node, "NMT state STOPPED in its heartbeat", FaultBit.INTERNAL)
            elif state == _NMT_OPERATIONAL:
                node.operational = True
            elif state == _NMT_PRE_OPERATIONAL and node.operational:
                self._fault(node, "NMT state PRE-OPERATIONAL in its heartbeat", FaultBit.INTERNAL)

    def _on_foreign(self, node: CanNode | None, can_id: int, data: bytearray) -> None:
        """A frame on a COB-ID only this master sends (NMT, SYNC, RPDO, SDO request): another master's."""
        if not self._started:
            return  # configuring: not yet a run to fault
        with self._changed:
            message = foreign_message(can_id, bytes(data))
            if node is None:
                self._fault_bits |= int(FaultBit.INTERNAL)
                if not self.faults or self.faults[-1] != f"bus: {message}":
                    self.faults.append(f"bus: {message}")
            else:
                self._fault(node, message, FaultBit.INTERNAL)
            self._changed.notify_all()

    def _fault(self, node: CanNode, what: str, bit: FaultBit) -> None:
        self._fault_bits |= int(bit)  # first: a command that sees the fault listed sees its bit
        message = f"{node.name}: {what}"
        if not self.faults or self.faults[-1] != message:
            self.faults.append(message)

    # ---- the device interface ---------------------------------------------------------------------

    def close(self) -> None:
        """Stops the master's heartbeat and leaves the bus."""
        network, self.network = self.network, None
        if self._heartbeat is not None:
            self._heartbeat.stop()
            self._heartbeat = None
        if network is not None:
            network.disconnect()

    def read(self, timeout_s: float) -> Reading | None:
        """The feedback of the last SYNC once every node's TPDO for it arrived; None after ``timeout_s``."""
        if self.network is None:
            raise DeviceError("the device is not open")
        if self.clock is not None:
            return self._read_clocked(timeout_s)
        held = self._last_feedback is not None and self._delivered == self._syncs
        resend_in = self._delivered_at + _RESEND_S - time.monotonic()
        with self._changed:
            ready = self._arrived(max(min(timeout_s, resend_in), 0.0) if held else timeout_s)
            if ready:
                self._deliver()
            elif not held or time.monotonic() < self._delivered_at + _RESEND_S:
                return None
            # else lockstep, no SYNC since the last feedback: it again, as the frame board re-sends its
            # unanswered one (the loop re-publishes a duplicate: the controller may have missed it)
            self._delivered_at = time.monotonic()
            return self._last_feedback

    def _read_clocked(self, timeout_s: float) -> Reading | None:
        """Real time: sends each SYNC when due; the feedback of the last one once its TPDOs arrived."""
        assert self.clock is not None
        deadline = time.monotonic_ns() + round(timeout_s * 1e9)
        while True:
            now = time.monotonic_ns()
            if now >= self.clock.due_ns:
                with self._changed:
                    self._sync()
            with self._changed:
                if self._arrived(max(min(deadline, self.clock.due_ns) - time.monotonic_ns(), 0) / 1e9):
                    return self._deliver()
            if time.monotonic_ns() >= deadline:
                return None

    def _arrived(self, timeout_s: float) -> bool:
        """Waits (lock held) for the last SYNC's TPDOs: in, late past their validity, or a fault untold.

        Late or untold: the nodes' last values go out with the fault bits (the loop faults).
        """
        self._changed.wait_for(lambda: self._tpdos_in() or self._untold(), timeout=timeout_s)
        ready = self._tpdos_in()
        late = self._watch() or self._untold()  # every read: a lost heartbeat is a fault, TPDOs or not
        return ready or (late and all(node.values for node in self.nodes))

    def _untold(self) -> bool:
        return bool(self._fault_bits & ~self._faults_delivered)

    def _tpdos_in(self) -> bool:
        return self._delivered < self._syncs and all(n.sync == self._syncs for n in self.nodes)

    def _deliver(self) -> FeedbackFrame:
        """The last SYNC's feedback, delivered (lock held): its faults are told."""
        self._delivered = self._syncs
        self._last_feedback = self._feedback()
        self._faults_delivered = self._fault_bits
        return self._last_feedback

    def _watch(self) -> bool:
        """Faults for lost heartbeats and for TPDOs late past their validity; True if this SYNC's are."""
        now, config = time.monotonic(), self.config
        consumer_s = 3 * config.heartbeat_ms / 1000.0
        for node in self.nodes:
            if not node.lost and now - node.heard > consumer_s:
                node.lost = True
                self._fault(
                    node, f"heartbeat lost (none for {3 * config.heartbeat_ms} ms)", FAULT_BIT[node.kind]
                )
        if self._delivered >= self._syncs or now - self._synced_at <= config.pdo_validity_ms / 1000.0:
            return False
        for node in self.nodes:
            if node.sync != self._syncs:
                what = f"TPDO1 of SYNC {self._syncs} not arrived within {config.pdo_validity_ms} ms"
                self._fault(node, what, FAULT_BIT[node.kind])
        return True

    def _feedback(self) -> FeedbackFrame:
        return feedback_frame(
            self.nodes,
            self.config,
            self.bridge,
            self.clock,
            syncs=self._syncs,
            boots=self._boots,
            host_session=self._host_session,
            last_seq=self._last_seq,
            estop=self._estop,
            fault_bits=self._fault_bits,
            dropped=sum(self.dropped.values()),
        )

    def write(self, command: ValveCommand) -> None:
        """The valves' RPDOs (control word and spool setpoint), then the SYNC: one control cycle.

        Lockstep: an enabled command that does not answer the last feedback given is dropped (counted).
        """
        if self.network is None:
            raise DeviceError("the device is not open")
        if command.enabled and self._syncs > self._delivered:
            # a second answer (to a feedback given again): its SYNC went out already, one step per feedback
            self.dropped["second_answer"] = self.dropped.get("second_answer", 0) + 1
            return
        stale = command.answers_seq != self._delivered % _U32
        if stale and command.flags == CommandFlag.ENABLE and self.clock is None:
            # lockstep: an answer to an older feedback (a copy given again, answered late) steps nothing,
            # as the frame board ticks only on an answer to its last feedback; the latest's answer steps
            # (an e-stop or re-arm is never dropped)
            self.dropped["stale_answer"] = self.dropped.get("stale_answer", 0) + 1
            return
        self._host_session, self._last_seq = command.session, command.seq
        if command.flags & CommandFlag.ESTOP:
            self._estop = True
        elif command.flags & CommandFlag.REARM:
            self._estop = False
            self._fault_bits = self._faults_delivered = 0  # acknowledged (the list kept); a valve still in
            # a fault state reports it again at its next TPDO
        codes = command.codes
        if any(abs(code) > SPOOL_FULL_SCALE for code in codes):
            self.dropped["code_limit"] = self.dropped.get("code_limit", 0) + 1
            codes = (0, 0)  # never beyond 100 % spool: refused, the valves to DISABLED
            enable = False
        else:
            enable = command.enabled and not self._estop and not self._fault_bits
        sync = self.clock is None and (enable or self._enabled or not self.config.sync_on_enabled)
        self._enabled = enable
        with self._changed:
            self._answered = self._delivered  # the SYNC whose feedback this command answers
            if self.clock is not None and self._answered == self._syncs:
                self.clock.on_answer(time.monotonic_ns())
            valves = [n for n in self.nodes if n.kind == "valve"]
            for node, code in zip(valves, codes, strict=True):
                word, setpoint = self._next(node, enable, code, bool(command.flags & CommandFlag.REARM))
                self._rpdo(node, word, setpoint)
            if sync:
                self._sync()

    def _next(self, node: CanNode, enable: bool, code: int, rearm: bool) -> tuple[int, int]:
        """Control word and setpoint: DISABLED -> HOLD -> ACTIVE a step a cycle if enabled; R on re-arm."""
        state = state_of_status(node.values[STATUS_WORD]) if node.values else None
        if state is not None and state.fault:
            return control_word(ValveState.DISABLED, reset=rearm), 0
        if not enable:
            return control_word(ValveState.DISABLED), 0
        if state in (ValveState.HOLD, ValveState.ACTIVE):
            return control_word(ValveState.ACTIVE), code
        return control_word(ValveState.HOLD), 0

    def _rpdo(self, node: CanNode, word: int, setpoint: int) -> None:
        rpdo = node.remote.rpdo[1]
        rpdo[CONTROL_WORD].raw = word
        rpdo[SPOOL_SETPOINT[0]].raw = setpoint
        rpdo.transmit()

    def _sync(self) -> None:
        assert self.network is not None
        data = b""
        if self.clock is not None:  # real time: the slot's SYNC counter tells the devices what passed
            self.clock.on_sync(time.monotonic_ns(), answered=self._answered == self._syncs)
            data = bytes([self.clock.counter])
        if self._delivered == self._syncs:  # validity counts from the first SYNC still unanswered
            self._synced_at = time.monotonic()
        self._syncs += 1
        self.network.send_message(SYNC_ID, data)

    def _send_safe(self) -> None:
        with self._changed:
            for node in self.nodes:
                if node.kind == "valve":
                    self._rpdo(node, control_word(ValveState.DISABLED), 0)
            self._sync()

    def make_safe(self) -> str | None:
        """Setpoint 0 and DISABLED to every valve: by RPDO and SYNC, and the control word by SDO (bounded).

        Returns None, or one line naming the valves not told by SDO and what stops them by themselves.
        """
        if self.network is None:
            return None
        self._send_safe()
        valves = [node for node in self.nodes if node.kind == "valve"]
        untold = tell_disabled(valves, self.config)
        for node in valves:
            if node.name in untold:
                what = f"control word DISABLED by SDO not told ({untold[node.name]})"
                self._fault(node, what, FaultBit.VALVE_DRIVER)
        return untold_line(valves, untold, self.config) if untold else None


def canopen_device(link: LinkConfig, canopen: CanopenConfig, bridge: BridgeConfig) -> CanopenDevice:
    """The CANopen bench the bridge's ``canopen.*`` describe."""
    return CanopenDevice(canopen, bridge=bridge, boot_wait_s=link.configure_timeout)
