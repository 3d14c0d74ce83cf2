"""Test-session set-up: every test runs in a private network namespace with only loopback.

At start-up the pytest process re-executes itself under ``unshare --net`` (``-r`` as well when not root),
with ``lo`` brought up by ``netns_exec.py``. Nodes started by tests, and DDS participants created inside the
test process, therefore cannot send a packet anywhere but loopback, whatever their discovery settings.
``ROS_AUTOMATIC_DISCOVERY_RANGE`` is set to ``LOCALHOST`` when unset, and each test gets its own
``ROS_DOMAIN_ID`` (fixture ``ros_domain_id``), so tests never see each other's graphs. Under pytest-xdist
(``make test``: ``-n 2``) every worker enters a namespace of its own at start-up and takes its ROS_DOMAIN_IDs
from a block of its own, so tests on two workers share no port (docs/TESTING.md, "Two workers").
"""

from __future__ import annotations

import itertools
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings
from ros_harness import DOMAIN_IDS, claim_domain_block, release_domain_blocks

_NETNS_MARKER = "SMM_TEST_PRIVATE_NETNS"
_NETNS_FAILURE = "SMM_TEST_NETNS_FAILURE"
_DOMAIN_IDS = pytest.StashKey[Iterator[int]]()
_HERE = Path(__file__).resolve().parent

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

# Hypothesis profiles (docs/TESTING.md). No deadline anywhere: tests never assert wall-clock times, and a
# shared machine's load must not fail a property. A test's own @settings (max_examples) wins over these.
#   ci        derandomized, no example database: the same examples on every run (selected when CI is set)
#   dev       random, with the local example database (the default on a workstation)
#   thorough  derandomized, many examples: `make mutation` and before a release
settings.register_profile(
    "ci",
    derandomize=True,
    database=None,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("dev", deadline=None)
settings.register_profile(
    "thorough",
    derandomize=True,
    database=None,
    deadline=None,
    max_examples=1000,
    # mutmut runs pytest several times in one process, so a test is seen from several executors.
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.differing_executors],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if os.environ.get("CI") else "dev"))


def _unshare_command() -> list[str]:
    command = ["unshare", "--net"]
    if os.geteuid() != 0:
        command.append("--map-root-user")
    return command


def _why_no_private_netns() -> str | None:
    if shutil.which("unshare") is None:
        return "the 'unshare' command (util-linux) is not installed"
    probe = subprocess.run([*_unshare_command(), "--", "true"], capture_output=True, text=True, check=False)
    if probe.returncode != 0:
        return f"'unshare --net' failed: {probe.stderr.strip() or probe.returncode} (run as root)"
    return None


def _session_domain_ids(config: pytest.Config) -> range:
    """The ROS_DOMAIN_IDs this session hands out: :data:`DOMAIN_IDS`; an xdist worker's own block of them."""
    worker = getattr(config, "workerinput", None)
    if worker is None:
        return DOMAIN_IDS
    try:  # the blocks' locks beside the workers' basetemps (<controller's basetemp>/popen-gw<i>)
        if not config.option.basetemp:
            raise RuntimeError("no basetemp from the controller (a local, popen, worker has one)")
        return claim_domain_block(Path(config.option.basetemp).parent, int(worker["workercount"]))
    except (OSError, RuntimeError, ValueError) as error:
        raise pytest.UsageError(
            f"xdist worker {worker['workerid']}: no ROS_DOMAIN_IDs of its own: {error}"
        ) from error


def pytest_configure(config: pytest.Config) -> None:
    """Registers the markers and the session's ROS_DOMAIN_IDs; re-executes the session in a fresh network
    namespace, once."""
    config.addinivalue_line(
        "markers",
        "cross_machine: compares numbers computed here with data made on another machine (the committed "
        "sample bag); `make test-other-cpu` runs these under other numeric paths (docs/TESTING.md)",
    )
    config.addinivalue_line(
        "markers",
        "xdist_group(name): the tests of one group run on one worker, one after another (make test's "
        "--dist loadgroup; docs/TESTING.md)",
    )
    config.stash[_DOMAIN_IDS] = itertools.cycle(_session_domain_ids(config))
    if os.environ.get(_NETNS_MARKER) == "1" or _NETNS_FAILURE in os.environ:
        return
    reason = _why_no_private_netns()
    if reason is not None:
        # Pure tests still run; every test that needs ROS fails with this reason (fixture ros_netns).
        os.environ[_NETNS_FAILURE] = reason
        return
    capture = config.pluginmanager.getplugin("capturemanager")
    if capture is not None:
        capture.suspend_global_capture(in_=True)
    sys.stdout.flush()
    sys.stderr.flush()
    os.environ[_NETNS_MARKER] = "1"
    argv = [sys.executable, "-m", "pytest", *config.invocation_params.args]
    os.chdir(config.invocation_params.dir)
    command = [*_unshare_command(), "--", sys.executable, str(_HERE / "netns_exec.py"), *argv]
    os.execvp(command[0], command)


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session: pytest.Session) -> None:
    """An xdist worker enters a network namespace of its own, or stops with the reason.

    Here, not in pytest_configure: the connections plugins open to the controller there (pytest-rerunfailures'
    status socket) stay in the controller's namespace; everything tests open comes later.
    """
    worker = getattr(session.config, "workerinput", None)
    if worker is None or _NETNS_FAILURE in os.environ:
        return  # no worker; or the controller had no namespace either: ROS tests fail with why (ros_netns)
    from netns_exec import enter_private_netns

    try:
        enter_private_netns()
    except (OSError, RuntimeError) as error:
        release_domain_blocks()  # this worker's process outlives the error: its replacement takes them
        raise pytest.UsageError(
            f"xdist worker {worker['workerid']}: no private network namespace: {error}"
        ) from error


@pytest.fixture(scope="session")
def ros_netns() -> None:
    """Fail (never skip) a ROS test that would run outside the private network namespace."""
    from netns_exec import interface_names

    if _NETNS_FAILURE in os.environ:
        pytest.fail(f"no private network namespace for ROS tests: {os.environ[_NETNS_FAILURE]}")
    names = interface_names()
    if names != ["lo"]:
        pytest.fail(f"ROS tests must run with loopback only, but interfaces are {names}")


@pytest.fixture
def ros_domain_id(
    ros_netns: None, monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest
) -> Iterator[int]:
    """A ROS_DOMAIN_ID of this test's own, exported to the environment of everything it starts."""
    domain_id = next(request.config.stash[_DOMAIN_IDS])
    monkeypatch.setenv("ROS_DOMAIN_ID", str(domain_id))
    monkeypatch.setenv(
        "ROS_AUTOMATIC_DISCOVERY_RANGE", os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    )
    yield domain_id


@pytest.fixture
def ros_context(ros_domain_id: int) -> Iterator[object]:
    """A private, initialised rclpy Context on this test's domain; shut down afterwards."""
    from ros_harness import private_context

    with private_context(ros_domain_id) as context:
        yield context


@pytest.fixture
def ros_processes(ros_domain_id: int, tmp_path: Path) -> Iterator[object]:
    """Start node processes for this test; every one is stopped and reaped at teardown."""
    from ros_harness import ProcessGroup

    group = ProcessGroup(log_dir=tmp_path / "logs")
    try:
        yield group
    finally:
        group.stop_all()
