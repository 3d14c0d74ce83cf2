"""Random and malformed frames on the CANopen link's bus: the oracle of docs/HW_CANOPEN.md holds."""

from __future__ import annotations

import pytest
from hw_bridge.canopen_fuzz import LINK_IDS, MASTER_ONLY, Injection, run_episode
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.slow

_payload = st.binary(min_size=0, max_size=8)
_codes = st.tuples(st.integers(-20_000, 20_000), st.integers(-20_000, 20_000))


@st.composite
def _injection(draw: st.DrawFn, ids: st.SearchStrategy[int]) -> Injection:
    return Injection(
        cycle=draw(st.integers(0, 5)),
        arbitration_id=draw(ids),
        data=draw(_payload),
        extended=draw(st.booleans()),
        remote=draw(st.booleans()) and draw(st.booleans()),  # a quarter: remote frames
    )


_any_id = st.one_of(st.integers(0, 0x7FF), st.sampled_from(LINK_IDS))
_FUZZ = settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@_FUZZ
@given(st.lists(_injection(_any_id), min_size=1, max_size=6), st.lists(_codes, min_size=6, max_size=6))
def test_random_frames_on_the_bus_keep_the_oracle(
    injections: list[Injection], codes: list[tuple[int, int]]
) -> None:
    outcome = run_episode(injections, codes)
    assert not outcome.violations, (outcome.violations, outcome.faults, injections)
    assert outcome.cycles == 4 + 6 + 2 and outcome.rpdos == 2 * outcome.cycles + 2  # the opening SYNC's too


@_FUZZ
@given(_injection(st.sampled_from(sorted(MASTER_ONLY))), st.lists(_codes, min_size=6, max_size=6))
def test_a_frame_only_a_master_sends_ends_in_a_named_fault_with_the_valves_disabled(
    injection: Injection, codes: list[tuple[int, int]]
) -> None:
    outcome = run_episode([injection], codes)
    assert not outcome.violations, (outcome.violations, outcome.faults, injection)
    if injection.changes_state:
        assert any(f"0x{injection.arbitration_id:03X} [" in fault for fault in outcome.faults), outcome.faults


@pytest.mark.parametrize(
    ("injection", "named"),
    [
        (Injection(2, 0x000, bytes([0x02, 0])), "bus: NMT command 0x000 [02 00] from another master"),
        (Injection(2, 0x080, b""), "bus: SYNC 0x080 [] from another master"),
        (Injection(2, 0x202, bytes([0x07, 0, 0x00, 0x40])), "valve beta (node 2): frame 0x202 [07 00 00 40]"),
    ],
    ids=["nmt-stop", "foreign-sync", "foreign-setpoint"],
)
def test_each_state_changing_frame_is_named(injection: Injection, named: str) -> None:
    outcome = run_episode([injection], [(2000, 2000)] * 4)
    assert not outcome.violations, outcome.violations
    assert any(fault.startswith(named) for fault in outcome.faults), outcome.faults


def test_the_oracle_sees_a_setpoint_beyond_full_scale() -> None:
    """The oracle can fail: a master that sent a code past 16384 would be caught (here: none is sent)."""
    outcome = run_episode([], [(16_385, 0)] * 2)
    assert not outcome.violations and outcome.rpdos > 0
