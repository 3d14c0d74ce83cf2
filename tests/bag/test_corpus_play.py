"""``smm-bag play`` of a foreign bag (MCAP, sqlite3) with a topic of a type not installed: one warning."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from bag.corpus.run import SMM_BAG
from bag.corpus.writers import NOT_INSTALLED, not_installed_bag
from rosbags.rosbag2.enums import StoragePlugin

pytestmark = pytest.mark.ros


@pytest.mark.parametrize("storage", [StoragePlugin.MCAP, StoragePlugin.SQLITE3], ids=["mcap", "sqlite3"])
def test_play_skips_a_topic_of_a_type_not_installed(
    ros_domain_id: int, tmp_path: Path, storage: StoragePlugin
) -> None:
    bag = not_installed_bag(tmp_path / "foreign", count=200, storage=storage)
    done = subprocess.run(
        [str(SMM_BAG), "play", str(bag), "--rate", "4"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    lines = done.stderr.splitlines()
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode == 0, done.stderr
    assert "/smm/joint_states: 200 messages published" in lines, done.stderr
    topic = NOT_INSTALLED[0]
    warnings = [line for line in lines if topic in line and "warn" in line.lower()]
    assert len(warnings) == 1, done.stderr
    assert not any(line.startswith(f"{topic}: ") and "published" in line for line in lines), done.stderr
