"""The idle-state hold: /dev/cpu_dma_latency held at 0 while open, released at exit, a refusal that says
what it costs and how to grant it; the setting read back (fake device and sysfs files, not this machine's)."""

from __future__ import annotations

import errno
import os
import struct
from pathlib import Path

import pytest
from smm_hw_bridge.idle_states import NO_LIMIT_US, IdleStates, hold_idle_states, read_idle_states


def _open_fd_targets() -> set[str]:
    targets = set()
    for entry in Path("/proc/self/fd").iterdir():
        try:
            targets.add(os.readlink(entry))
        except OSError:
            continue
    return targets


def test_the_hold_writes_a_32_bit_limit_and_keeps_the_device_open_until_closed(tmp_path: Path) -> None:
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"")
    hold = hold_idle_states(0, device)
    assert hold.held
    assert device.read_bytes() == struct.pack("=i", 0)
    assert str(device) in _open_fd_targets()  # the kernel keeps the request while the file is open
    assert f"holding {device} at 0 us" in hold.statement and "released at exit" in hold.statement
    hold.close()
    assert not hold.held
    assert str(device) not in _open_fd_targets()
    hold.close()  # idempotent


def test_the_hold_is_released_when_its_block_ends(tmp_path: Path) -> None:
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"")
    with hold_idle_states(7, device) as hold:
        assert hold.held and device.read_bytes() == struct.pack("=i", 7)
    assert not hold.held and str(device) not in _open_fd_targets()


@pytest.mark.parametrize(
    ("error", "reason"),
    [
        (errno.EACCES, "permission denied"),
        (errno.EPERM, "not permitted"),
        (errno.EROFS, "read-only"),
        (errno.ENOENT, "absent"),
    ],
)
def test_a_device_it_cannot_open_is_not_held_and_says_the_cost_and_the_grant(
    tmp_path: Path, error: int, reason: str
) -> None:
    def refuse(_path: str, _flags: int) -> int:
        raise OSError(error, os.strerror(error))

    hold = hold_idle_states(0, tmp_path / "cpu_dma_latency", opener=refuse)
    assert not hold.held
    text = hold.statement
    assert "cannot hold" in text and reason in text
    assert "deep idle states" in text and "delays the loop" in text  # the cost
    assert "as root" in text and "udev rule" in text and "chmod" in text  # the grant


def test_a_missing_device_is_absent(tmp_path: Path) -> None:
    hold = hold_idle_states(0, tmp_path / "no_such_device")
    assert not hold.held and "absent" in hold.statement


def test_a_device_that_refuses_the_write_is_closed_and_not_held(tmp_path: Path) -> None:
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"")
    hold = hold_idle_states(0, device, opener=lambda path, _flags: os.open(path, os.O_RDONLY))
    assert not hold.held and "cannot hold" in hold.statement
    assert str(device) not in _open_fd_targets()


@pytest.mark.parametrize("limit", [-1, 2**31, True, 0.0])
def test_a_limit_out_of_range_is_refused(tmp_path: Path, limit: object) -> None:
    with pytest.raises(ValueError, match="limit_us"):
        hold_idle_states(limit, tmp_path / "cpu_dma_latency")  # type: ignore[arg-type]


def _sysfs(root: Path, states: list[tuple[str, int]]) -> Path:
    for index, (name, latency) in enumerate(states):
        folder = root / f"state{index}"
        folder.mkdir(parents=True)
        (folder / "name").write_text(f"{name}\n")
        (folder / "latency").write_text(f"{latency}\n")
    return root


def test_the_setting_is_read_with_the_idle_states_in_order(tmp_path: Path) -> None:
    states = [(f"C{i}", i * 10) for i in range(12)]  # state10, state11 sort after state9
    cpuidle = _sysfs(tmp_path / "cpuidle", states)
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(struct.pack("=i", 0))
    read = read_idle_states(device, cpuidle)
    assert read == IdleStates(0, tuple(states))
    assert read.held
    assert read.statement().startswith("CPU wake-up latency limit 0 us (held")
    assert "C11 110 us" in read.statement()


@pytest.mark.parametrize(("limit", "held"), [(0, True), (1, True), (2, False), (NO_LIMIT_US, False)])
def test_held_means_no_state_slower_than_the_fastest_is_allowed(
    tmp_path: Path, limit: int, held: bool
) -> None:
    cpuidle = _sysfs(tmp_path / "cpuidle", [("POLL", 0), ("C1", 2), ("C6", 133)])
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(struct.pack("=i", limit))
    read = read_idle_states(device, cpuidle)
    assert read.held is held
    if limit == NO_LIMIT_US:
        assert "no limit (every idle state allowed)" in read.statement()


def test_an_unreadable_setting_says_why(tmp_path: Path) -> None:
    short = tmp_path / "short"
    short.write_bytes(b"\0\0")
    for device, why in ((tmp_path / "absent", "No such file"), (short, "read 2 bytes")):
        read = read_idle_states(device, tmp_path / "no_cpuidle")
        assert read.limit_us is None and not read.held
        assert "limit unknown" in read.statement() and why in read.statement()
        assert "no cpuidle states listed" in read.statement()
