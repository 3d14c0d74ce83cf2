"""The CANopen nodes' last TPDOs as one :data:`~smm_hw_bridge.device.Feedback` (docs/HW_CANOPEN.md). Pure."""

from __future__ import annotations

from smm_hw_bridge.bridge_config import BridgeConfig
from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.canopen_node import CanNode
from smm_hw_bridge.cia408 import (
    POSITION,
    PRESSURE_ACTUAL,
    SPOOL_ACTUAL,
    SPOOL_FULL_SCALE,
    STATUS_WORD,
    ValveState,
    state_of_status,
)
from smm_hw_bridge.protocol import ADC_MAX, NO_COMMAND_AGE, FeedbackFrame, StatusBit
from smm_hw_bridge.sync_clock import SyncClock

__all__ = ["feedback_frame"]

_U32 = 1 << 32


def feedback_frame(
    nodes: list[CanNode],
    config: CanopenConfig,
    bridge: BridgeConfig,
    clock: SyncClock | None,
    *,
    syncs: int,
    boots: int,
    host_session: int,
    last_seq: int,
    estop: bool,
    fault_bits: int,
    dropped: int,
) -> FeedbackFrame:
    """The feedback of SYNC ``syncs`` from every node's last TPDO (each node has sent one).

    The load pressures go out as the A/D codes ``bridge.pressure`` reads back, the supply as
    ``config.supply_bar``'s code; ``tick`` counts 1 ms ticks, on ``clock``'s schedule in real time.
    """
    valves = [n for n in nodes if n.kind == "valve"]
    encoders = [n for n in nodes if n.kind == "encoder"]
    states = [state_of_status(v.values[STATUS_WORD]) for v in valves]
    status = int(StatusBit.HOST_LOCKED) if host_session else 0
    if all(state is ValveState.ACTIVE for state in states):
        status |= int(StatusBit.ENABLED)
    if estop:
        status |= int(StatusBit.ESTOP_LATCHED)
    scale, bar_per_unit = bridge.pressure, config.bar_per_unit
    load = [
        scale.zero_code[j] + v.values[PRESSURE_ACTUAL[0]] * bar_per_unit / scale.bar_per_code[j]
        for j, v in enumerate(valves)
    ]
    adc = [config.supply_bar / bridge.supply_bar_per_code, *load, 0.0]
    spool = tuple(max(-SPOOL_FULL_SCALE, min(SPOOL_FULL_SCALE, v.values[SPOOL_ACTUAL[0]])) for v in valves)
    ticks = config.period_us // 1000 or 1
    tick = syncs * ticks
    if clock is not None:  # the schedule's slot; the age counts skipped slots and a late answer
        tick = clock.slot * ticks
        age = clock.age * ticks if host_session else NO_COMMAND_AGE
    else:
        age = 0 if host_session else NO_COMMAND_AGE
    return FeedbackFrame(
        session=boots % _U32 or 1,
        seq=syncs % _U32,
        tick=tick % _U32,
        host_session=host_session,
        counts=(encoders[0].values[POSITION] % _U32, encoders[1].values[POSITION] % _U32),
        adc=tuple(min(max(round(value), 0), ADC_MAX) for value in adc),  # type: ignore[arg-type]
        status=status,
        faults=fault_bits & 0xFFFF,
        applied_seq=last_seq,
        applied_age=age,
        output_codes=(spool[0], spool[1]),
        late_commands=0,
        crc_errors=0,
        dropped_frames=dropped % _U32,
    )
