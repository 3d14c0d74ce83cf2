"""Link faults on request: each kind does exactly what it says to the next frames."""

from __future__ import annotations

import pytest
from smm_bench_emulator.faults import LinkFault, LinkFaults

FRAMES = [bytes([i]) * 8 for i in range(1, 9)]


def run(faults: LinkFaults) -> list[bytes]:
    out: list[bytes] = []
    for tick, frame in enumerate(FRAMES):
        out += faults.outgoing(frame, tick)
    return out


def test_no_fault_passes_everything() -> None:
    assert run(LinkFaults()) == FRAMES


def test_drop_and_silent() -> None:
    faults = LinkFaults()
    faults.request("drop", 2)
    assert run(faults) == FRAMES[2:]
    faults.request(LinkFault.SILENT, 5)
    assert run(faults) == FRAMES[5:]


def test_duplicate() -> None:
    faults = LinkFaults()
    faults.request("duplicate", 1)
    assert run(faults) == [FRAMES[0], *FRAMES]


def test_reorder_swaps_pairs() -> None:
    faults = LinkFaults()
    faults.request("reorder", 2)
    assert run(faults) == [FRAMES[1], FRAMES[0], FRAMES[3], FRAMES[2], *FRAMES[4:]]


def test_delay_holds_frames_for_ticks() -> None:
    faults = LinkFaults()
    faults.request("delay", 2, ticks=3)
    assert run(faults) == [*FRAMES[2:3], FRAMES[0], FRAMES[3], FRAMES[1], *FRAMES[4:]]


def test_corrupt_changes_one_byte() -> None:
    faults = LinkFaults(seed=1)
    faults.request("corrupt", 3)
    out = run(faults)
    assert len(out) == len(FRAMES)
    changed = [sum(a != b for a, b in zip(x, y, strict=True)) for x, y in zip(out, FRAMES, strict=True)]
    assert changed == [1, 1, 1, 0, 0, 0, 0, 0]


def test_drop_commands_applies_to_incoming_only() -> None:
    faults = LinkFaults()
    faults.request("drop_commands", 1)
    assert run(faults) == FRAMES
    assert faults.incoming(b"x") is None and faults.incoming(b"y") == b"y"


def test_bad_requests_are_rejected() -> None:
    faults = LinkFaults()
    with pytest.raises(ValueError):
        faults.request("explode")
    with pytest.raises(ValueError):
        faults.request("drop", 0)
    with pytest.raises(ValueError):
        faults.request("delay", 1, ticks=-1)
