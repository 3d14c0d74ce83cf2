"""The emulated CANopen bench: every node PRE-OPERATIONAL after its boot-up; the valves' pressure actual
0x6381:01, the load pressure exactly (to the unit) without transducer noise, with ``pressure_noise`` about it
with that standard deviation, seeded."""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import can
import numpy as np
import pytest
from smm_bench_emulator.canopen_bench import CanBench, CanBenchConfig

_CHANNELS = itertools.count()


def sent_and_load(noise: float, syncs: int = 400) -> Iterator[tuple[list[int], list[float]]]:
    """Per SYNC of a bench at rest: each valve's 0x6381:01 sent and its load pressure (units)."""
    bench = CanBench(
        CanBenchConfig(pressure_noise=noise), can.Bus(interface="virtual", channel=f"noise-{next(_CHANNELS)}")
    )
    try:
        for node in (*(valve.node for valve in bench.valves), *bench.encoders):
            node.nmt.state = "OPERATIONAL"
        for _ in range(syncs):
            with bench.lock:
                bench.step()
                sent = [int(valve.node.tpdo[1][0x6381].raw) for valve in bench.valves]
                load = [bar / bench.config.bar_per_unit for bar in bench.board.valves.load_pressure()]
            yield sent, load
    finally:
        bench.close()


def test_without_noise_the_load_pressure_is_sent_to_the_unit() -> None:
    for sent, load in sent_and_load(0.0, 50):
        assert sent == [round(value) for value in load]


def test_the_transducer_noise_has_its_standard_deviation_and_its_seed() -> None:
    first = list(sent_and_load(0.05))
    errors = np.array([np.subtract(sent, load) for sent, load in first])
    assert errors.std(axis=0) == pytest.approx([5.0, 5.0], rel=0.15)  # 0.05 bar in 0.01 bar units
    assert abs(errors.mean()) < 1.0
    assert [sent for sent, _ in first] == [sent for sent, _ in sent_and_load(0.05)]  # the board's seed


def test_a_negative_noise_is_refused() -> None:
    with pytest.raises(ValueError, match="pressure_noise"):
        CanBenchConfig(pressure_noise=-0.1)


def test_every_node_is_pre_operational_after_its_boot_up_and_its_heartbeat_says_so() -> None:
    """Not INITIALISING: a heartbeat started by the master's 0x1017 write would be a boot-up (state 0)."""
    channel = f"noise-{next(_CHANNELS)}"
    bench = CanBench(CanBenchConfig(), can.Bus(interface="virtual", channel=channel))
    listener = can.Bus(interface="virtual", channel=channel)
    try:
        nodes = (*(valve.node for valve in bench.valves), *bench.encoders)
        assert [node.nmt.state for node in nodes] == ["PRE-OPERATIONAL"] * 4
        nodes[0].sdo[0x1017].raw = 50  # the master's write of the producer time
        message = listener.recv(5.0)
        assert message is not None and message.arbitration_id == 0x700 + nodes[0].id
        assert list(message.data) == [127]
    finally:
        listener.shutdown()
        bench.close()
