"""Configuring the CANopen link: the bridge's settings checked against the link before any bus traffic.

Nodes checked by SDO (missing, wrong type or identity, mapping, bus load): test_canopen_device.py and
test_canopen_faults.py.
"""

from __future__ import annotations

import re

import can
import pytest
from hw_bridge import test_canopen_device as emulated
from smm_bench_emulator.canopen_bench import CanBench
from smm_hw_bridge.canopen_device import ConfigureError
from smm_hw_bridge.core import BridgeConfig
from smm_hw_bridge.device import open_device
from smm_hw_bridge.transport import LinkConfig
from smm_hw_bridge.valve_output import ValveOutputConfig

bench = emulated.bench  # the emulated bench on a fresh virtual channel (fixtures)
channel = emulated.channel
_VALVE = ValveOutputConfig(code_limit=(16384, 16384))


@pytest.mark.parametrize(
    ("period_us", "divider", "fits"),
    [
        (1000, 5, r"set canopen\.period_us to 5000 \(or bridge\.control_divider to 1\)$"),
        (5000, 1, r"set canopen\.period_us to 1000 \(or bridge\.control_divider to 5\)$"),
        (2500, 2, r"set canopen\.period_us to 2000$"),  # no divider gives 2.5 ms
        (20_000, 10, r"set canopen\.period_us to 10000$"),  # nor 20 ms: 10 at most
    ],
)
def test_a_sync_period_not_the_control_period_is_refused_naming_both_and_the_fit(
    channel: str, period_us: int, divider: int, fits: str
) -> None:
    spy = can.Bus(interface="virtual", channel=channel)
    try:
        canopen = emulated._config(channel=channel, period_us=period_us, receive_deadline_ms=100)
        bridge = BridgeConfig(valve=_VALVE, control_divider=divider)
        with pytest.raises(ConfigureError) as refused:  # the bridge's own path: link.transport canopen
            open_device(LinkConfig(transport="canopen"), canopen, bridge)
        message = str(refused.value)
        assert message.startswith(
            f"canopen.period_us {period_us} us does not match bridge.control_divider {divider}: one SYNC a "
            "control period is 1000 x bridge.control_divider us"
        ), message
        assert re.search(fits, message), message
        assert spy.recv(0.2) is None  # refused before any frame: no SDO, no NMT, no SYNC
    finally:
        spy.shutdown()


def test_a_sync_period_of_the_control_divider_configures(bench: CanBench, channel: str) -> None:
    canopen = emulated._config(channel=channel, period_us=5000, receive_deadline_ms=50)
    device = open_device(
        LinkConfig(transport="canopen"), canopen, BridgeConfig(valve=_VALVE, control_divider=5)
    )
    try:
        assert len(device.found) == 4
    finally:
        device.close()
