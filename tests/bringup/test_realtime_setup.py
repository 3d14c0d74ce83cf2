"""What smm-launch sets up for a real-time run: the idle states held (a fake device), the recorder under
SCHED_FIFO only with the CPUs for it, a preflight refusal never respawned."""

from __future__ import annotations

import os
import stat
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from smm_bringup.graph_nodes import DIRECT_LOOP, EMULATOR_NODE, RECORDER_NODE, SIM_NODE, NodeSpec
from smm_bringup.realtime import OBSERVER_NICE, Scheduling, fifo, nice, observer_fifo_allowed
from smm_bringup.supervisor import (
    EXIT_PREFLIGHT_REFUSED,
    RespawnPolicy,
    hold_idle_states_for,
    launch_processes,
)

from smm_bringup import supervisor

LOOP = [
    NodeSpec("p", "e", EMULATOR_NODE, "", rt_priority=70),
    NodeSpec("p", "e", DIRECT_LOOP, "", rt_priority=55),
]
RECORDER = NodeSpec("p", "e", RECORDER_NODE, "", rt_priority=40)


def test_a_real_time_run_holds_the_idle_states_for_its_length_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"")
    with hold_idle_states_for(LOOP, device) as hold:
        assert hold is not None and hold.held
        assert device.read_bytes() == struct.pack("=i", 0)
        assert f"idle states: holding {device} at 0 us" in capsys.readouterr().out
    assert not hold.held
    assert f"idle states: released {device}" in capsys.readouterr().out


def test_a_run_without_real_time_priorities_leaves_the_idle_states_alone(tmp_path: Path) -> None:
    device = tmp_path / "cpu_dma_latency"
    device.write_bytes(b"")
    with hold_idle_states_for([NodeSpec("p", "e", SIM_NODE, "")], device) as hold:
        assert hold is None
    assert device.read_bytes() == b""


def test_a_device_it_cannot_hold_is_said_on_stderr_and_the_run_goes_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with hold_idle_states_for(LOOP, tmp_path / "absent") as hold:
        assert hold is not None and not hold.held
    err = capsys.readouterr().err
    assert "idle states: cannot hold" in err and "as root" in err


@pytest.mark.parametrize(
    ("loop", "cpus", "allowed"), [(2, 2, False), (2, 3, False), (2, 4, True), (1, 2, False), (1, 3, True)]
)
def test_an_observer_runs_real_time_only_with_a_cpu_for_it_and_one_spare(
    loop: int, cpus: int, allowed: bool
) -> None:
    assert observer_fifo_allowed(loop, cpus) is allowed


@pytest.mark.parametrize(("cpus", "recorder_fifo"), [(2, False), (3, False), (4, True)])
def test_the_recorder_runs_at_normal_priority_without_the_cpus_for_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], cpus: int, recorder_fifo: bool
) -> None:
    monkeypatch.setattr(supervisor, "fifo_allowed", lambda _priority: True)
    monkeypatch.setattr(supervisor.os, "sched_getaffinity", lambda _pid: set(range(cpus)))
    schedulings = supervisor._schedulings([RECORDER, *LOOP])
    assert schedulings[EMULATOR_NODE] == fifo(70) and schedulings[DIRECT_LOOP] == fifo(55)  # kept
    assert schedulings[RECORDER_NODE] == (fifo(40) if recorder_fifo else nice(OBSERVER_NICE))
    said = f"{RECORDER_NODE} at normal policy, nice {OBSERVER_NICE}: 2 loop process(es) under SCHED_FIFO"
    assert (said in capsys.readouterr().out) is not recorder_fifo


def test_a_nice_value_is_set_under_normal_scheduling_for_the_process_and_its_session() -> None:
    probe = (
        "import os, pathlib; group = pathlib.Path('/proc/self/autogroup'); "
        "print(os.sched_getscheduler(0), os.getpriority(os.PRIO_PROCESS, 0), "
        "group.read_text().split()[-1] if group.exists() else 'none', end='')"
    )
    niced = subprocess.run(
        [sys.executable, "-c", probe],
        preexec_fn=nice(-5).preexec(),
        start_new_session=True,  # as GraphProcesses starts a node: a session, so an autogroup, of its own
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    policy, niceness, group = niced.split()
    before = os.getpriority(os.PRIO_PROCESS, 0)
    try:
        os.setpriority(os.PRIO_PROCESS, 0, -5)
        allowed = True
    except OSError:
        allowed = False
    os.setpriority(os.PRIO_PROCESS, 0, before)  # raising a nice value back is always allowed
    assert int(policy) == os.SCHED_OTHER
    assert int(niceness) == (-5 if allowed else before)  # refused: the child starts as it was
    assert group in ("none", "-5" if allowed else "0")  # no autogroups (kernel option off): nothing to set


def test_a_preflight_refusal_is_not_respawned() -> None:
    assert not RespawnPolicy().applies(NodeSpec("p", "e", DIRECT_LOOP, ""), EXIT_PREFLIGHT_REFUSED)


def test_a_refusing_loop_is_started_once_and_stops_the_graph_with_exit_4(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    starts = tmp_path / "starts"
    for name, body in (
        ("refuser", f"echo $$ >> {starts}\nexit {EXIT_PREFLIGHT_REFUSED}"),
        ("plant", "while true; do sleep 0.05; done"),
    ):
        path = tmp_path / name
        path.write_text(f"#!/bin/sh\n{body}\n")
        path.chmod(path.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    graph = [
        NodeSpec("no_such_package", "plant", SIM_NODE, "m:C"),
        NodeSpec("no_such_package", "refuser", DIRECT_LOOP, ""),
    ]
    code = launch_processes(graph, stop_grace_s=2.0, respawn=RespawnPolicy(delay_s=0.0, limit=5))
    assert code == EXIT_PREFLIGHT_REFUSED
    assert len(starts.read_text().split()) == 1
    assert (
        "refused to arm at preflight (not respawned: final until a person changes" in capsys.readouterr().err
    )


def test_the_started_line_names_the_scheduling_as_before() -> None:
    assert (fifo(70).describe(), nice(-10).describe(), Scheduling().describe()) == (
        ", SCHED_FIFO 70",
        ", nice -10",
        "",
    )
    assert Scheduling().preexec() is None and fifo(0).preexec() is None  # nothing to set: no preexec_fn


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"priority": -5}, "priority must be an int in"),
        ({"priority": 100}, "priority must be an int in"),
        ({"priority": True}, "priority must be an int in"),
        ({"nice": -21}, "nice must be an int in"),
        ({"nice": 20}, "nice must be an int in"),
        ({"priority": 10, "nice": -5}, "SCHED_FIFO 10 has no nice value"),
    ],
)
def test_a_scheduling_out_of_range_or_both_at_once_is_refused(kwargs: dict[str, int], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Scheduling(**kwargs)
