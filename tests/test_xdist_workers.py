"""make test's xdist workers: each in a network namespace of its own (only ``lo``, multicast routed over it)
with a block of ROS_DOMAIN_IDs of its own, a crashed one's going to its replacement; a worker that cannot
enter its namespace stops the run."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from ros_harness import DOMAIN_IDS, worker_domain_ids
from xdist_probe import OUT

REPO = Path(__file__).resolve().parents[1]
PROBE = Path(__file__).with_name("xdist_probe.py")


def run_probe(
    tmp_path: Path, *options: str, **env: str
) -> tuple[subprocess.CompletedProcess[str], list[Any]]:
    """``pytest tests/xdist_probe.py --dist each options`` (every worker runs every probe test): the run and
    what each probe test saw."""
    seen = tmp_path / "seen"
    seen.mkdir()
    command = [sys.executable, "-m", "pytest", str(PROBE), "--dist", "each", "-q", *options]
    command += ["-p", "no:cacheprovider", "--basetemp", str(tmp_path / "basetemp")]
    environment = {**os.environ, OUT: str(seen), **env}
    done = subprocess.run(
        command, cwd=REPO, env=environment, capture_output=True, text=True, timeout=600, check=False
    )
    return done, [json.loads(path.read_text()) for path in sorted(seen.glob("*.json"))]


@pytest.mark.slow
def test_each_worker_has_a_network_namespace_and_domain_ids_of_its_own(
    ros_netns: None, tmp_path: Path
) -> None:
    done, seen = run_probe(tmp_path, "-n", "2")
    assert done.returncode == 0, done.stdout + done.stderr
    by_worker = {name: [s for s in seen if s["worker"] == name] for name in ("gw0", "gw1")}
    assert [len(records) for records in by_worker.values()] == [3, 3], seen
    namespaces = {name: {s["netns"] for s in records} for name, records in by_worker.items()}
    assert [len(inodes) for inodes in namespaces.values()] == [1, 1]  # one for all of a worker's tests
    controller = {s["controller_netns"] for s in seen}
    assert len(controller) == 1
    assert len(namespaces["gw0"] | namespaces["gw1"] | controller) == 3, (namespaces, controller)
    for s in seen:  # the whole worker (its main thread, the process) and what its tests start
        assert s["process_netns"] == s["started_process_netns"] == s["netns"]
        assert s["interfaces"] == ["lo"]
        assert s["multicast"] == [s["turn"]]  # python-can's udp_multicast, routed over lo
    ids = {name: {s["domain_id"] for s in records} for name, records in by_worker.items()}
    assert [len(block) for block in ids.values()] == [3, 3]  # each test its own
    assert ids["gw0"].isdisjoint(ids["gw1"]), ids
    assert all(0 <= domain_id <= 232 for domain_id in ids["gw0"] | ids["gw1"])


@pytest.mark.slow
def test_a_worker_without_its_namespace_stops_the_run(ros_netns: None, tmp_path: Path) -> None:
    no_ip = str(Path(sys.executable).parent)  # for the multicast route
    done, seen = run_probe(tmp_path, "-n", "1", "--max-worker-restart", "0", PATH=no_ip)
    assert done.returncode != 0
    said = done.stdout + done.stderr
    assert "xdist worker gw0: no private network namespace: no multicast route over lo" in said, said
    assert seen == []


@pytest.mark.parametrize("count", [1, 2, 3, 7, len(DOMAIN_IDS)])
def test_the_workers_blocks_of_domain_ids_are_disjoint_valid_ids(count: int) -> None:
    blocks = [worker_domain_ids(index, count) for index in range(count)]
    ids = [domain_id for block in blocks for domain_id in block]
    assert len(ids) == len(set(ids)) and all(len(block) >= 1 for block in blocks)
    assert set(ids) <= set(DOMAIN_IDS) and min(ids) >= 0 and max(ids) <= 232  # Fast DDS's range
    assert len(ids) > len(DOMAIN_IDS) - count  # at most count - 1 left unused


@pytest.mark.parametrize(("index", "count"), [(-1, 2), (2, 2), (0, 0), (0, len(DOMAIN_IDS) + 1)])
def test_a_worker_outside_the_blocks_is_refused(index: int, count: int) -> None:
    with pytest.raises(ValueError, match=f"block {index} of {count}"):
        worker_domain_ids(index, count)


CLAIM = (
    "import sys, time; from pathlib import Path; from ros_harness import claim_domain_block\n"
    "try:\n    print(claim_domain_block(Path(sys.argv[1]), 2), flush=True)\n"
    "except RuntimeError as error:\n    print(error, flush=True)\n    sys.exit(1)\n"
    "time.sleep(120)\n"
)
"""A worker's claim of one of two blocks (printed), held for two minutes."""


def test_a_crashed_workers_block_goes_to_the_worker_that_replaces_it(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parent)}
    claims: list[subprocess.Popen[str]] = []

    def claim() -> str:
        claims.append(
            subprocess.Popen(
                [sys.executable, "-c", CLAIM, str(tmp_path)], stdout=subprocess.PIPE, text=True, env=env
            )
        )
        assert claims[-1].stdout is not None
        return claims[-1].stdout.readline().strip()

    try:
        assert [claim(), claim()] == [str(worker_domain_ids(0, 2)), str(worker_domain_ids(1, 2))]
        assert claim() == f"all 2 blocks of ROS_DOMAIN_IDs are held by live processes ({tmp_path})"
        assert claims[-1].wait(60) == 1
        claims[0].kill()  # gw0 crashes
        claims[0].wait(60)
        assert claim() == str(worker_domain_ids(0, 2))  # its replacement
    finally:
        for process in claims:
            process.kill()
            process.wait(60)
