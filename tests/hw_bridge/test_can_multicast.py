"""The emulated CAN bus over udp_multicast stays on loopback; the master drives the bench over it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from netns_exec import interface_names  # type: ignore[import-not-found]
from smm_bench_emulator.canopen_bench import CanBench, CanBenchConfig, eds_path
from smm_hw_bridge.can_multicast import check_loopback_route, loopback_multicast_bus
from smm_hw_bridge.canopen_config import CanopenConfig
from smm_hw_bridge.canopen_device import CanopenDevice
from smm_hw_bridge.cia408 import ValveState
from smm_hw_bridge.device import DeviceError
from smm_hw_bridge.protocol import FeedbackFrame
from udp_bench import answer

GROUP = "239.74.163.2"


def emulated_bench_config(port: int) -> CanopenConfig:
    """The master's settings for the emulated bench on ``GROUP``:``port`` with its shipped EDS files."""
    return CanopenConfig(
        channel=GROUP,
        port=port,
        valve_eds=str(eds_path("valve_cia408.eds")),
        encoder_eds=str(eds_path("encoder_cia406.eds")),
    )


def test_the_group_routes_over_loopback_only(ros_netns: None) -> None:
    assert interface_names() == ["lo"]
    check_loopback_route(GROUP)
    route = subprocess.run(["ip", "-4", "route", "get", GROUP], capture_output=True, text=True, check=True)
    assert " dev lo " in f" {route.stdout} "


def test_a_namespace_without_the_route_is_refused(ros_netns: None) -> None:
    probe = (
        "from smm_hw_bridge.can_multicast import loopback_multicast_bus, MulticastRouteError\n"
        "try:\n    loopback_multicast_bus('239.74.163.2', 43113)\n"
        "except MulticastRouteError as error:\n    print('refused:', error)\n"
    )
    done = subprocess.run(
        ["unshare", "--net", "--", sys.executable, "-c", probe], capture_output=True, text=True, check=True
    )
    assert "refused: multicast group 239.74.163.2 goes over" in done.stdout, done.stdout + done.stderr
    assert "not lo" in done.stdout


def test_the_master_drives_the_bench_over_udp_multicast(ros_netns: None) -> None:
    bench = CanBench(CanBenchConfig(), loopback_multicast_bus(GROUP, 43114))
    device = CanopenDevice(emulated_bench_config(43114))
    try:
        device.open()
        feedback = device.read(5.0)
        for seq in range(1, 6):
            assert isinstance(feedback, FeedbackFrame), feedback
            device.write(answer(feedback, seq, (1000, 1000), session=3))
            feedback = device.read(5.0)
        assert bench.valve_states() == (ValveState.ACTIVE, ValveState.ACTIVE)
        device.make_safe()
        assert bench.valve_states() == (ValveState.DISABLED, ValveState.DISABLED)
    finally:
        device.close()
        bench.close()


def test_an_unopenable_interface_is_a_device_error() -> None:
    config = CanopenConfig(interface="no-such-interface", valve_eds="v", encoder_eds="e")
    with pytest.raises(DeviceError, match="cannot open CAN interface no-such-interface"):
        CanopenDevice(config).open()


def test_the_emulator_process_refuses_a_group_that_leaves_loopback(ros_netns: None) -> None:
    done = subprocess.run(
        [
            "unshare",
            "--net",
            "--",
            sys.executable,
            "-m",
            "smm_bench_emulator.cli",
            "--link",
            "canopen",
            "--mode",
            "lockstep",
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    assert done.returncode == 2, done.stdout + done.stderr
    assert "multicast group 239.74.163.2 goes over" in done.stderr and "not lo" in done.stderr


def test_the_emulator_process_runs_its_duration_of_live_syncs_in_lockstep(
    ros_netns: None, tmp_path: Path
) -> None:
    status_file = tmp_path / "board.json"
    emulator = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "smm_bench_emulator.cli",
            "--link",
            "canopen",
            "--mode",
            "lockstep",
            "--can-port",
            "43115",
            "--duration",
            "0.02",
            "--status-file",
            str(status_file),
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert emulator.stdout is not None
    assert "CANopen bench on 239.74.163.2:43115" in emulator.stdout.readline()  # nodes up before configure
    device = CanopenDevice(emulated_bench_config(43115))
    try:
        device.open()
        feedback = device.read(5.0)
        seq = 0
        while emulator.poll() is None and seq < 1000:
            assert isinstance(feedback, FeedbackFrame), feedback
            seq += 1
            device.write(answer(feedback, seq, (500, 500), session=3))
            feedback = device.read(2.0) or feedback
    finally:
        device.close()
    assert emulator.wait(timeout=30) == 0
    status = json.loads(status_file.read_text())
    assert status["live_ticks"] == 20 and status["verdict"] is None
    assert status["enabled_ticks"] >= 19  # live from the first SYNC with both valves ACTIVE
