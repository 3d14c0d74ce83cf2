"""The independent bench's clock: a SYNC moves its plant the cycle period (0x1006) times the periods its
counter says passed (CiA 301), 1 ms steps; lockstep's SYNC without a counter moves it one period."""

from __future__ import annotations

from collections.abc import Iterator

import can
import pytest
from hw_bridge.independent_bench.bench import IndependentBench

ACTIVE = 0x7  # control word D H M


@pytest.fixture
def bench() -> Iterator[IndependentBench]:
    bus = can.Bus(interface="virtual", channel="independent-bench-clock")
    made = IndependentBench(bus)
    for node in made.valve_nodes:
        node.sdo[0x1006].raw = 5000  # 200 Hz, as the master writes it
    yield made
    made.close()


def _sync(bench: IndependentBench, data: bytes) -> None:
    bench.received = [(ACTIVE, 0), (ACTIVE, 0)]  # both valves answered: ACTIVE, the plant live
    bench._on_sync(0x80, bytearray(data), 0.0)


def test_the_sync_counter_moves_the_plant_the_periods_that_passed(bench: IndependentBench) -> None:
    _sync(bench, b"\x01")
    assert bench.live_steps == 5 and bench.skipped == 0
    _sync(bench, b"\x04")  # slots 2 and 3 skipped
    assert bench.live_steps == 20 and bench.skipped == 2
    assert bench.plant.t == pytest.approx(0.020)


def test_the_counter_wraps_after_240(bench: IndependentBench) -> None:
    _sync(bench, b"\xef")  # 239
    _sync(bench, b"\x02")  # 240, 1, 2: three periods
    assert bench.live_steps == 5 + 15 and bench.skipped == 2


def test_a_sync_without_a_counter_moves_one_period(bench: IndependentBench) -> None:
    for _ in range(3):
        _sync(bench, b"")
    assert bench.live_steps == 15 and bench.skipped == 0


def test_its_duration_is_live_plant_time() -> None:
    made = IndependentBench(
        can.Bus(interface="virtual", channel="independent-bench-duration"), duration_s=0.02
    )
    try:
        for node in made.valve_nodes:
            node.sdo[0x1006].raw = 5000
        _sync(made, b"\x01")
        assert not made.done.is_set()
        _sync(made, b"\x04")
        assert made.done.is_set()
    finally:
        made.close()


def test_an_unknown_clock_is_refused() -> None:
    with pytest.raises(ValueError, match="clock must be one of"):
        IndependentBench(can.Bus(interface="virtual", channel="independent-bench-refused"), clock="tick")
