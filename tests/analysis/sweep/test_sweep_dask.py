"""smm-sweep on a real Dask cluster: a scheduler and two workers as separate processes on loopback."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
from smm_analysis.batch import INDEX_NAMES
from smm_analysis.sweep.execute import SchedulerError, batches, finished_batches, read_parts, run_sweep
from smm_analysis.sweep.spec import parse_spec

DASK = str(Path(sys.executable).with_name("dask"))

SPEC: dict[str, Any] = {
    "name": "dask",
    "controller": "fpdeso",
    "scenarios": ["case2"],
    "duration": 0.15,
    "gains": {"fpdeso.fuzzy.kd0": {"range": [80.0, 130.0]}, "td.filter_factor[1]": {"grid": [0.001, 0.002]}},
    "sampling": {"method": "random", "count": 6, "seed": 5},
    "plant_draws": {"count": 2, "seed": 1, "parameters": {"seed": {"integers": [0, 10_000]}}},
    "objectives": ["RMS_alpha", "eps_u_alpha"],
    "batch_size": 2,
}


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class Cluster:
    """A Dask scheduler and workers started as processes; every one is killed and reaped at the end."""

    def __init__(self, log_dir: Path) -> None:
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.log_dir = log_dir
        self.processes: list[subprocess.Popen[bytes]] = []
        self.scheduler = self._start(
            "scheduler",
            [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(self.port), "--no-dashboard"],
        )
        self.workers = [
            self._start(
                f"worker{index}",
                [
                    DASK,
                    "worker",
                    self.address,
                    "--nthreads",
                    "1",
                    "--no-nanny",
                    "--no-dashboard",
                    "--host",
                    "127.0.0.1",
                ],
            )
            for index in range(2)
        ]
        from distributed import Client

        with Client(self.address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=120)

    def _start(self, name: str, argv: list[str]) -> subprocess.Popen[bytes]:
        log = (self.log_dir / f"{name}.log").open("wb")
        env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
        process = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env)
        self.processes.append(process)
        return process

    def kill(self, process: subprocess.Popen[bytes]) -> None:
        """SIGKILL one of this cluster's processes (by its pid) and reap it."""
        if process.poll() is None:
            os.kill(process.pid, signal.SIGKILL)
        process.wait(timeout=30)

    def stop(self) -> None:
        for process in self.processes:
            self.kill(process)


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[Cluster]:
    started = Cluster(tmp_path)
    try:
        yield started
    finally:
        started.stop()


def _rows(out: Path) -> np.ndarray:
    table = read_parts(out)
    return np.stack(
        [table.column(name).to_numpy().astype(float) for name in ("run_id", *INDEX_NAMES)], axis=-1
    )


def test_a_sweep_on_dask_equals_the_local_run_row_by_row_even_when_a_worker_dies(
    cluster: Cluster, tmp_path: Path
) -> None:
    spec = parse_spec(SPEC)
    local = tmp_path / "local"
    run_sweep(spec, local)

    def kill_a_worker(done: int, total: int) -> None:
        if done == 1:
            cluster.kill(cluster.workers[0])

    remote = tmp_path / "remote"
    ran = run_sweep(spec, remote, scheduler=cluster.address, progress=kill_a_worker)
    assert ran == len(batches(spec))
    assert cluster.workers[0].poll() is not None
    assert np.array_equal(_rows(local), _rows(remote), equal_nan=True)
    assert pq.read_table(next((remote / "parts").glob("*.parquet"))).num_rows == 2


def test_a_scheduler_that_dies_mid_sweep_is_named_and_the_finished_batches_are_kept(
    cluster: Cluster, tmp_path: Path
) -> None:
    spec = parse_spec(SPEC)
    out = tmp_path / "out"

    def kill_the_scheduler(done: int, total: int) -> None:
        if done == 1:
            cluster.kill(cluster.scheduler)

    with pytest.raises(SchedulerError, match=cluster.address):
        run_sweep(spec, out, scheduler=cluster.address, progress=kill_the_scheduler)
    kept = finished_batches(out)
    assert kept and len(kept) < len(batches(spec))
    assert run_sweep(spec, out) == len(batches(spec)) - len(kept)  # the rest, locally
    local = tmp_path / "local"
    run_sweep(spec, local)
    assert np.array_equal(_rows(local), _rows(out), equal_nan=True)
